"""A route no curve follows to the goal is planned part of the way (safety/partway.py)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers.planner_world import default_scenario

from services.planner.decline import keeps_path_in_force, keeps_safer_path
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D, plan_path
from services.planner.safety.partway import (
    APPROACH_BACK_R,
    PARTWAY_SHARES,
    partway_goals,
    plan_partway,
    route_point,
)

SCENARIO = default_scenario()
ROUTE = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 40.0]])  # 70 m with one corner


ORIGIN = Pose2D(x=0.0, y=0.0, theta=0.0)
CORNER_GOAL = Pose2D(x=30.0, y=40.0, theta=1.57)  # ROUTE's end, along its last leg
GOAL_95 = Pose2D(x=95.0, y=20.0, theta=0.0)  # the default mission's goal


def _request(
    r_min_m: float = 6.5,
    *,
    fix_goal_heading: bool = True,
    start: Pose2D = ORIGIN,
    goal: Pose2D = CORNER_GOAL,
) -> PlanRequest:
    return PlanRequest(
        start=start,
        goal=goal,
        area=SCENARIO.world.area,
        obstacles=Obstacles(),
        vehicle_radius_m=SCENARIO.vehicle.radius_m,
        r_min_m=r_min_m,
        v_ref_mps=SCENARIO.vehicle.cruise_speed_mps,
        fix_goal_heading=fix_goal_heading,
    )


FAILED = PlanResult(
    status="NO_PATH", reason="no feasible curve", strategy="no_curve", grid_path=ROUTE
)


def test_a_route_point_lies_on_the_route_at_its_arc_length() -> None:
    assert route_point(ROUTE, 0.0) == (0.0, 0.0)
    assert route_point(ROUTE, 15.0) == (15.0, 0.0)
    assert route_point(ROUTE, 30.0) == (30.0, 0.0)
    assert route_point(ROUTE, 50.0) == (30.0, 20.0)
    assert route_point(ROUTE, 1e3) == (30.0, 40.0)  # clamped to its ends
    assert route_point(ROUTE, -1.0) == (0.0, 0.0)


def test_partway_plans_to_a_point_along_the_route_heading_free_and_short_of_the_goal() -> None:
    asked: list[PlanRequest] = []

    def pipeline(q: PlanRequest) -> PlanResult:
        asked.append(q)
        return PlanResult(status="OK", reason="", strategy="searched", grid_path=ROUTE[:2])

    got = plan_partway(_request(), FAILED, pipeline)
    assert got is not None and got.ok and got.short_of_goal and got.partway
    assert len(asked) == 1 and not asked[0].fix_goal_heading
    assert (asked[0].goal.x, asked[0].goal.y) == route_point(ROUTE, PARTWAY_SHARES[0] * 70.0)
    assert got.reason.startswith(
        "no feasible curve; partway to (30.0, 5.0), 35 of the route's 70 m"
    )


def test_partway_tries_each_share_then_the_approaches_then_gives_up() -> None:
    asked: list[Pose2D] = []

    def nothing(q: PlanRequest) -> PlanResult:
        asked.append(q.goal)
        return PlanResult(status="NO_PATH", reason="no", strategy="no_curve")

    assert plan_partway(_request(fix_goal_heading=False), FAILED, nothing) is None
    assert len(asked) == len(PARTWAY_SHARES)
    # a goal held with its heading: then the approach points behind it
    asked.clear()
    assert plan_partway(_request(), FAILED, nothing) is None
    assert len(asked) == len(PARTWAY_SHARES) + len(APPROACH_BACK_R)
    # a share nearer the start than R_min along the route is not tried
    asked.clear()
    assert plan_partway(_request(r_min_m=25.0, fix_goal_heading=False), FAILED, nothing) is None
    assert [(g.x, g.y) for g in asked] == [route_point(ROUTE, 35.0), route_point(ROUTE, 52.5)]
    no_route = dataclasses.replace(FAILED, grid_path=ROUTE[:1])
    assert plan_partway(_request(fix_goal_heading=False), no_route, nothing) is None


def test_the_approach_points_lie_behind_the_goal_along_its_heading() -> None:
    req = dataclasses.replace(_request(), goal=Pose2D(x=95.0, y=20.0, theta=0.0))
    approaches = [(x, y) for x, y, why in partway_goals(req, ROUTE[:1]) if "approach" in why]
    assert approaches == [(95.0 - k * 6.5, 20.0) for k in APPROACH_BACK_R]


def test_a_vehicle_that_overran_its_goal_comes_round_for_another_approach() -> None:
    # just past the goal, heading away from it, the route to it shorter than a turn: no share
    # of it is a partway goal (configs/ocean.toml, fuzzy PID, seed 710 held here, drifting,
    # for the rest of the run); a real plan reaches the first approach point behind the goal
    req = _request(start=Pose2D(x=98.4, y=21.0, theta=math.radians(105.0)), goal=GOAL_95)
    failed = dataclasses.replace(FAILED, grid_path=np.array([[98.4, 21.0], [95.0, 20.0]]))
    got = plan_partway(req, failed, lambda q: plan_path(q, SCENARIO.planner))
    assert got is not None and got.ok and got.short_of_goal, failed.reason
    assert "an approach 2 R_min behind the goal" in got.reason
    end = got.curve().ctrl[-1]  # a clamped curve ends on its last control point
    assert math.hypot(end[0] - 95.0, end[1] - 20.0) == pytest.approx(APPROACH_BACK_R[0] * 6.5)


@pytest.mark.parametrize("why", ["corridor", "cruise"])
def test_a_precaution_that_finds_only_a_partway_plan_keeps_the_path_in_force(why: str) -> None:
    partway = PlanResult(
        status="OK", reason="partway", strategy="partway", short_of_goal=True, partway=True
    )
    declined = keeps_path_in_force(why, partway, has_path=True, stepping_aside=False)
    assert declined is not None and "partway" in declined.detail
    # a path in force that has failed (or none) takes it: a receding-horizon step on
    assert keeps_path_in_force("infeasible", partway, has_path=True, stepping_aside=False) is None
    assert keeps_path_in_force(why, partway, has_path=False, stepping_aside=False) is None


def test_a_plan_whose_rollout_breaks_clearance_before_the_path_in_force_stops_is_declined() -> None:
    # a turn about whose rollout falls 0.4 m short 2.5 s on, for a conflict the path in force
    # stops short of in 9 s (decline.py keeps_safer_path)
    turn = PlanResult(
        status="OK",
        reason="turned first",
        strategy="turned_first",
        flown_short_m=0.4,
        flown_short_at_s=2.5,
    )
    declined = keeps_safer_path("infeasible", turn, safe_for_s=9.0)
    assert declined is not None and declined.code == "kept_safer_path"
    assert "0.40 m short" in declined.detail and "9.0 s" in declined.detail
    # the path in force stops sooner than the breach: the plan is taken
    assert keeps_safer_path("infeasible", turn, safe_for_s=2.0) is None
    # a plan whose rollout keeps its clearance, or a replan not for a conflict ahead
    clear = dataclasses.replace(turn, flown_short_m=0.0, flown_short_at_s=math.inf)
    assert keeps_safer_path("infeasible", clear, safe_for_s=9.0) is None
    assert keeps_safer_path("deviation", turn, safe_for_s=9.0) is None


def test_a_vehicle_late_beside_a_goal_held_with_its_heading_goes_to_it_heading_free() -> None:
    # ocean, fuzzy PID seed 1404: late on its last bend it passed 7 m south of the goal
    # heading 44 deg, R_min over ground 9.6 m; no curve joins the goal's heading 0 from there,
    # and the approach behind it was found only after it had passed (then held and drifted
    # to the area's edge, NO_PATH 140 times). The mission asks only to reach the goal.
    req = _request(9.6, start=Pose2D(x=91.5, y=13.9, theta=0.77), goal=GOAL_95)
    got = plan_path(req, SCENARIO.planner)
    assert got.ok and got.strategy == "heading_freed" and not got.short_of_goal, got.reason
    assert "with its heading free" in got.reason
    end = got.curve().ctrl[-1]
    assert math.hypot(end[0] - 95.0, end[1] - 20.0) < 1e-9
    assert got.max_curvature < 1.0 / 9.6
    # far from the goal the heading is held: the same bend 40 m back finds a curve that joins it
    far = dataclasses.replace(req, start=Pose2D(x=51.5, y=13.9, theta=0.77))
    got = plan_path(far, SCENARIO.planner)
    assert got.ok and "heading_freed" not in got.tried
