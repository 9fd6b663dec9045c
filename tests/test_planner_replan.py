"""ReplanPolicy: quiet without events, one test per event, minimum interval between replans."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from helpers.planner_world import circle, default_scenario, moving_circle

from common.config.planner import PlannerConfig
from services.planner.plan import PlanRequest, PlanResult, plan_path
from services.planner.replan import ReplanPolicy, replan_request
from services.planner.result import Obstacles, Pose2D

CFG = PlannerConfig(corridor_halfwidth_m=3.0, deviation_threshold_m=2.0, min_replan_interval_s=1.0)
V = 1.5
R_VEH = default_scenario().vehicle.radius_m
START = Pose2D(x=5.0, y=20.0, theta=0.0)
GOAL = Pose2D(x=95.0, y=20.0, theta=0.0)
NONE = Obstacles()


def _planned() -> tuple[ReplanPolicy, PlanResult]:
    """A policy holding a straight path y = 20 from x = 5 to 95, planned at t = 0."""
    res = plan_path(PlanRequest(start=START, goal=GOAL, v_ref_mps=V, vehicle_radius_m=R_VEH), CFG)
    assert res.ok
    pol = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    pol.on_planned(0.0, res, GOAL, NONE)
    return pol, res


def _on_path(t: float, dy: float = 0.0) -> Pose2D:
    return Pose2D(x=5.0 + V * t, y=20.0 + dy, theta=0.0)


def test_no_replan_without_an_event() -> None:
    pol, _ = _planned()
    far = Obstacles(
        circles=(circle(x=50.0, y=35.0, radius=2.0),),  # 12.9 m from the path
        moving=(moving_circle(id=4, x=50.0, y=2.0, vx=0.5, vy=0.0, radius=1.0),),  # parallel, 17 m
    )
    for t in np.arange(0.0, 40.0, 0.5):
        d = pol.check(float(t), _on_path(float(t), dy=0.5), GOAL, far)
        assert not d.replan, d


def test_no_path_yet_and_after_a_failed_attempt() -> None:
    pol = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    d = pol.check(0.0, START, GOAL, NONE)
    assert d.replan and d.reason == "no_path"
    walled_off = PlanResult(status="NO_PATH", reason="walled off", strategy="no_route")
    pol.on_planned(0.0, walled_off, GOAL, NONE)
    assert not pol.check(0.5, START, GOAL, NONE).replan  # minimum interval 1 s
    d = pol.check(1.0, START, GOAL, NONE)
    assert d.replan and d.reason == "no_path"


def test_deviation_beyond_the_threshold_and_the_minimum_interval() -> None:
    pol, _ = _planned()
    assert not pol.check(0.5, _on_path(0.5, dy=3.0), GOAL, NONE).replan  # too soon
    assert not pol.check(2.0, _on_path(2.0, dy=1.9), GOAL, NONE).replan  # 1.9 m < 2 m
    d = pol.check(3.0, _on_path(3.0, dy=2.2), GOAL, NONE)
    assert d.replan and d.reason == "deviation"
    assert d.conflict_s == math.inf  # only an infeasible path has a point of conflict


def test_static_obstacle_on_the_path_ahead_makes_it_infeasible() -> None:
    pol, _ = _planned()
    blocker = Obstacles(circles=(circle(x=60.0, y=20.5, radius=1.0),))
    d = pol.check(5.0, _on_path(5.0), GOAL, blocker)
    assert d.replan and d.reason == "infeasible"
    # the first point of conflict: where the path comes within r + rho0 of the circle's edge
    first = 60.0 - math.sqrt((1.0 + R_VEH + CFG.rho0_m) ** 2 - 0.5**2) - START.x
    assert first <= d.conflict_s <= first + 0.3, (d.conflict_s, first)  # the sample after it
    behind = Obstacles(circles=(circle(x=8.0, y=20.5, radius=0.5),))  # already passed
    assert not pol.check(10.0, _on_path(10.0), GOAL, behind).replan


def test_a_plan_with_an_escape_in_a_field_without_static_obstacles() -> None:
    # a plan leaving the margin of a moving obstacle has escape_m > 0; with no static
    # obstacle the policy's static distances are empty, which the escape mask must allow for
    # (it raised a broadcast error mid-mission on the crossing scenario)
    _, res = _planned()
    pol = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    pol.on_planned(0.0, dataclasses.replace(res, escape_m=3.0), GOAL, NONE)
    assert not pol.check(2.0, _on_path(2.0), GOAL, NONE).replan


def test_moving_obstacle_predicted_on_the_path_makes_it_infeasible() -> None:
    pol, _ = _planned()
    # crosses y = 20 at x = 50 at t = 30 s, when the vehicle (x = 5 + 1.5 t) is there too
    crossing = moving_circle(id=7, x=50.0, y=5.0, vx=0.0, vy=0.5, radius=1.0)
    d = pol.check(0.0 + 1.0, _on_path(1.0), GOAL, Obstacles(moving=(crossing.advanced(1.0),)))
    assert d.replan and d.reason == "infeasible"
    # the conflict starts before the crossing point (x = 50: s = 45), ahead of the vehicle
    assert 1.5 < d.conflict_s < 45.0


def test_new_track_entering_the_corridor() -> None:
    pol, _ = _planned()
    # passes 2 m (hull gap ~1.9 m) below the path when the vehicle is there: safe (> rho0)
    # but inside the 3 m corridor, and unknown to the current plan
    near = moving_circle(id=9, x=50.0, y=5.0, vx=0.0, vy=(17.0 - 5.0) / 30.0, radius=1.0)
    d = pol.check(1.0, _on_path(1.0), GOAL, Obstacles(moving=(near.advanced(1.0),)))
    assert d.replan and d.reason == "corridor", d
    # a track the plan already accounted for (inside the corridor at plan time) is tolerated
    res = plan_path(PlanRequest(start=START, goal=GOAL, v_ref_mps=V, vehicle_radius_m=R_VEH), CFG)
    pol2 = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    pol2.on_planned(0.0, res, GOAL, Obstacles(moving=(near,)))
    assert not pol2.check(1.0, _on_path(1.0), GOAL, Obstacles(moving=(near.advanced(1.0),))).replan


def test_a_declined_replan_counts_its_tracks_as_accounted_for_and_restarts_the_interval() -> None:
    pol, _ = _planned()
    near = moving_circle(id=9, x=50.0, y=5.0, vx=0.0, vy=(17.0 - 5.0) / 30.0, radius=1.0)
    seen = Obstacles(moving=(near.advanced(1.0),))
    assert pol.check(1.0, _on_path(1.0), GOAL, seen).reason == "corridor"
    pol.on_kept(1.0, seen)  # the replan it asked for was declined (core.py): path kept
    assert not pol.check(1.5, _on_path(1.5), GOAL, Obstacles(moving=(near.advanced(1.5),))).replan
    assert not pol.check(3.0, _on_path(3.0), GOAL, Obstacles(moving=(near.advanced(3.0),))).replan
    # ... and eq. (12)-(13) still judge it: should it head for the path, the path is infeasible
    onto = dataclasses.replace(near.advanced(3.0), vy=(20.0 - near.advanced(3.0).y) / 27.0)
    assert pol.check(3.0, _on_path(3.0), GOAL, Obstacles(moving=(onto,))).reason == "infeasible"


def test_goal_change_triggers_and_replans_start_from_the_current_pose() -> None:
    pol, _ = _planned()
    new_goal = Pose2D(x=90.0, y=30.0, theta=0.0)
    d = pol.check(2.0, _on_path(2.0), new_goal, NONE)
    assert d.replan and d.reason == "goal_changed"
    here = _on_path(2.0, dy=0.3)
    req = replan_request(
        PlanRequest(start=START, goal=new_goal, vehicle_radius_m=R_VEH), here, NONE
    )
    assert req.start == here and req.goal == new_goal
    res = plan_path(req, CFG)
    assert res.ok and np.allclose(res.control_points[0], [here.x, here.y])
    pol.on_planned(2.0, res, new_goal, NONE)
    assert not pol.check(3.5, here, new_goal, NONE).replan


def test_short_of_the_start_only_the_offset_to_the_side_deviates() -> None:
    # a plan made for where the vehicle would be once it was made came sooner: the vehicle is
    # still behind its start, on the way to it; 3 m behind is no deviation, 3 m aside is
    pol, _ = _planned()
    behind = Pose2D(x=START.x - 3.0, y=20.3, theta=0.0)
    assert not pol.check(2.0, behind, GOAL, NONE).replan
    aside = Pose2D(x=START.x - 1.0, y=23.0, theta=0.0)
    d = pol.check(3.5, aside, GOAL, NONE)
    assert d.replan and d.reason == "deviation" and d.detail.startswith("3.00 m"), d


def test_a_slower_plan_asks_for_cruise_speed_once_past_where_it_was_slowed() -> None:
    # rollout.py made the plan for half the speed, to hold a bend 30 m along it: past that the
    # vehicle would crawl to its goal with no other event to replan on
    res = plan_path(
        PlanRequest(start=START, goal=GOAL, v_ref_mps=V / 2, vehicle_radius_m=R_VEH), CFG
    )
    slowed = dataclasses.replace(res, v_ref_mps=V / 2, slow_until_m=30.0)
    pol = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    pol.on_planned(0.0, slowed, GOAL, NONE)

    def at(t: float) -> Pose2D:
        return Pose2D(x=START.x + V / 2 * t, y=20.0, theta=0.0)

    for t in np.arange(1.0, 59.0, 1.0):  # 0.75 m/s for 30 m: 40 s
        d = pol.check(float(t), at(float(t)), GOAL, NONE)
        if START.x + V / 2 * t - START.x < 29.5:
            assert not d.replan, (t, d)
        elif d.replan:
            break
    assert d.replan and d.reason == "cruise" and "back to 1.50 m/s" in d.detail
    assert 30.0 <= V / 2 * t <= 31.0
    pol.on_planned(t, res, GOAL, NONE)  # a plan at cruise speed ends it
    assert not pol.check(t + 2.0, Pose2D(x=START.x + 1.5, y=20.0, theta=0.0), GOAL, NONE).replan


def test_a_way_aside_asks_for_the_goal_again_at_every_interval() -> None:
    # evade.py: no plan reached the goal, and the vehicle steps aside from a moving obstacle
    res = plan_path(
        PlanRequest(
            start=START, goal=Pose2D(x=15.0, y=20.0, theta=0.0), v_ref_mps=V, vehicle_radius_m=R_VEH
        ),
        CFG,
    )
    pol = ReplanPolicy(CFG, vehicle_radius_m=R_VEH, v_ref_mps=V)
    pol.on_planned(0.0, dataclasses.replace(res, short_of_goal=True), GOAL, NONE)
    assert not pol.check(0.5, _on_path(0.5), GOAL, NONE).replan  # the minimum interval
    d = pol.check(1.0, _on_path(1.0), GOAL, NONE)
    assert d.replan and d.reason == "aside" and "short of the goal" in d.detail
    pol.on_planned(1.0, res, GOAL, NONE)  # an ordinary plan ends it
    assert not pol.check(2.0, _on_path(1.0), GOAL, NONE).replan


def test_a_path_kept_cut_short_of_a_conflict_is_planned_again_once_the_conflict_is_gone() -> None:
    pol, _ = _planned()
    crossing = moving_circle(id=9, x=50.0, y=5.0, vx=0.0, vy=15.0 / 30.0, radius=1.0)
    d = pol.check(1.0, _on_path(1.0), GOAL, Obstacles(moving=(crossing.advanced(1.0),)))
    assert d.replan and d.reason == "infeasible" and math.isfinite(d.conflict_s)
    # its replacement was declined (decline.py keeps_safer_path): the path in force is kept,
    # stopping short of the conflict; once the crossing is gone it would stop there for good
    pol.on_kept(1.0, Obstacles(moving=(crossing.advanced(1.0),)), cut_short=True)
    assert not pol.check(1.5, _on_path(1.5), GOAL, NONE).replan  # the interval holds
    d = pol.check(2.0, _on_path(2.0), GOAL, NONE)
    assert d.replan and d.reason == "infeasible" and not math.isfinite(d.conflict_s), d
    # a plan put in force ends it
    pol.on_planned(2.0, _planned()[1], GOAL, NONE)
    assert not pol.check(3.5, _on_path(1.5), GOAL, NONE).replan
