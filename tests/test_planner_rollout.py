"""A plan flown before it is adopted (services/planner/safety/rollout.py): the controller on the
response model measures how near the vehicle will come, and a plan it would fly inside rho0
is made again wider."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers.planner_world import default_scenario

from common.config.planner import PlannerConfig
from common.config.world import CircleObstacleConfig
from common.world import ObstacleState
from common.world.geometry import Box
from services.control.command.response import ResponseModel
from services.control.controllers import Limits, make_controller
from services.planner.asking import PlanAsk
from services.planner.geometry.nurbs_curve import clamped_uniform_knots
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D
from services.planner.safety.intent import IntentObstacle
from services.planner.safety.rollout import (
    RolloutInputs,
    plan_and_verify,
    roll_out,
    rollout_clearance,
)

SCENARIO = default_scenario()
CFG = SCENARIO.planner
R = SCENARIO.vehicle.radius_m
V = SCENARIO.vehicle.cruise_speed_mps
W_MAX = V / SCENARIO.vehicle.turn_radius_min_m  # the hardest turn at cruise speed


def _plan_through(ctrl: np.ndarray, length_m: float) -> PlanResult:
    """An OK plan of a degree-3 NURBS with these control points (N, 2), unit weights."""
    return PlanResult(
        status="OK",
        reason="",
        strategy="searched",
        degree=3,
        control_points=ctrl,
        weights=np.ones(len(ctrl)),
        knots=clamped_uniform_knots(len(ctrl), 3),
        length_m=length_m,
    )


def _straight(y: float, x0: float = 5.0, x1: float = 60.0) -> PlanResult:
    """An OK plan along the line y from x0 to x1 (evenly spaced control points)."""
    return _plan_through(np.column_stack([np.linspace(x0, x1, 8), np.full(8, y)]), x1 - x0)


def _request(*, circles: tuple[CircleObstacleConfig, ...] = (), moving=()) -> PlanRequest:
    return PlanRequest(
        start=Pose2D(x=5.0, y=20.0, theta=0.0),
        goal=Pose2D(x=60.0, y=20.0, theta=0.0),
        area=SCENARIO.world.area,
        obstacles=Obstacles(circles=circles, moving=tuple(moving)),
        vehicle_radius_m=R,
        r_min_m=SCENARIO.vehicle.turn_radius_min_m,
        v_ref_mps=V,
    )


def _flight(w0: float = 0.0, v0: float = V, start_std_m: float = 0.0) -> RolloutInputs:
    limits = Limits.from_vehicle(SCENARIO.vehicle, yaw_lag_lead=True)
    return RolloutInputs(
        controller=make_controller(SCENARIO.controller, limits),
        model=ResponseModel.from_vehicle(SCENARIO.vehicle),
        step_s=CFG.period_s,
        start=(5.0, 20.0, 0.0, v0, w0),
        start_std_m=start_std_m,
        t0=0.0,
    )


def _ask(req: PlanRequest, cfg: PlannerConfig, rollout: RolloutInputs) -> PlanAsk:
    """A plan asked for req with the hull's own R_min the request's, and no way aside."""
    return PlanAsk(req=req, r_water_m=req.r_min_m, cfg=cfg, rollout=rollout)


def _circle_left_of_the_line(gap_m: float, x: float = 12.0) -> CircleObstacleConfig:
    """A circle whose surface is gap_m from the hull of a vehicle on the line y = 20."""
    radius = 2.0
    return CircleObstacleConfig(id=1, x_m=x, y_m=20.0 + R + gap_m + radius, radius_m=radius)


def test_a_flight_on_its_path_clears_what_the_path_clears() -> None:
    gap = CFG.rho0_m + 0.3
    f = rollout_clearance(
        _straight(20.0), _request(circles=(_circle_left_of_the_line(gap),)), _flight(), CFG
    )
    assert f.off_path_m < 0.02
    assert abs(f.min_clearance_m - gap) < 0.02
    assert abs(f.x - 12.0) < 0.2 and abs(f.t_s - 7.0 / V) < 1.0


def test_a_plan_made_from_one_flown_is_not_flown_again_nor_its_curve_tabulated() -> None:
    # coded or given its reason (dataclasses.replace), a plan carries the same curve: its
    # flight, reference and PlannedPath are those of the plan it was made from, in both currents
    first, req = _straight(20.0), _request()
    model = ResponseModel.from_vehicle(SCENARIO.vehicle)
    fm = dataclasses.replace(_flight(), doubt=model.with_current(0.3, 0.1))
    flown = roll_out(first, req, fm, CFG.tuning)
    coded = dataclasses.replace(first.coded("remade_wider"), reason="flown")
    assert roll_out(coded, req, fm, CFG.tuning) is flown
    doubted = fm.doubted()
    assert doubted is not None
    in_doubt = roll_out(coded, req, doubted, CFG.tuning)
    assert in_doubt is not flown and in_doubt.ref is flown.ref
    assert coded.planned_path() is first.planned_path() is flown.ref.path
    # measured when verified and again (soon) for contact: among the same obstacles, once
    rollout_clearance(first, req, fm, CFG)
    measured = flown.measured[0]
    soon = rollout_clearance(coded, req, fm, CFG, within_s=5.0)
    assert flown.measured[0] is measured
    assert soon.t_s <= 5.0  # its own horizon: the distances beyond it masked on a copy
    assert np.isfinite(measured[4]).all()
    other = dataclasses.replace(first, control_points=first.control_points.copy())
    assert roll_out(other, req, fm, CFG.tuning) is not flown
    assert other.planned_path() is not first.planned_path()


def test_a_vehicle_turning_the_other_way_flies_the_start_of_its_path_wide() -> None:
    # the same straight path, the vehicle turning hard left as it starts: its yaw loop takes
    # a while to unwind, and it swings toward the obstacle on its left
    gap = CFG.rho0_m + 0.3
    req = _request(circles=(_circle_left_of_the_line(gap, x=9.0),))
    straight = rollout_clearance(_straight(20.0), req, _flight(w0=0.0), CFG)
    turning = rollout_clearance(_straight(20.0), req, _flight(w0=W_MAX), CFG)
    assert straight.off_path_m < 0.02 and turning.off_path_m > 0.05
    assert turning.min_clearance_m < straight.min_clearance_m - 0.05


def test_moving_obstacles_count_over_the_flights_first_seconds_only() -> None:
    def crossing_at(t_s: float) -> ObstacleState:
        # comes down across the line y = 20 at x = 5 + V t_s, reaching it at t_s
        return ObstacleState(
            id=9,
            x=5.0 + V * t_s,
            y=20.0 + 1.0 * t_s,
            vx=0.0,
            vy=-1.0,
            ax=0.0,
            ay=0.0,
            radius=1.0,
            moving=True,
        )

    def roll_out(meets_at_s: float) -> float:
        req = _request(moving=[crossing_at(meets_at_s)])
        return rollout_clearance(_straight(20.0), req, _flight(), CFG).min_clearance_m

    soon, late = roll_out(8.0), roll_out(CFG.tuning.rollout_moving_s + 8.0)
    assert soon < 0.0  # they meet
    # they would meet too, after the window: only where it is within it counts (metres away)
    assert late > 5.0


def test_another_vehicles_broadcast_route_counts_over_the_whole_flight() -> None:
    # the same meeting after the window, the crosser now another vehicle whose route (its
    # plan, broadcast) comes down across the line: a plan, not a guess, so it counts
    meet_s = CFG.tuning.rollout_moving_s + 8.0
    x_meet, v_other = 5.0 + V * meet_s, 1.0
    ys = np.linspace(20.0 + v_other * meet_s, 0.0, 50)
    xs = np.full_like(ys, x_meet)
    s_route = 20.0 + v_other * meet_s - ys  # arc length down the route from its start
    other = IntentObstacle(
        id=9, x=x_meet, y=float(ys[0]), vx=0.0, vy=-v_other, ax=0.0, ay=0.0, radius=1.0,
        moving=True, route_x=xs, route_y=ys, s_route=s_route, route_box=Box.of(xs, ys),
        s0=0.0, speed=v_other,
    )  # fmt: skip
    f = rollout_clearance(_straight(20.0), _request(moving=[other]), _flight(), CFG)
    assert f.min_clearance_m < 0.0 and not f.static  # they meet, and the flight says so
    assert abs(f.t_s - meet_s) < 1.5


def test_the_escape_stretch_is_not_held_to_rho0() -> None:
    circle = _circle_left_of_the_line(0.2, x=7.0)  # 0.2 m from the hull, 2 m after the start
    req = _request(circles=(circle,))
    assert rollout_clearance(_straight(20.0), req, _flight(), CFG).min_clearance_m < 0.25
    escaping = dataclasses.replace(_straight(20.0), escape_m=6.0)
    assert rollout_clearance(escaping, req, _flight(), CFG).min_clearance_m > 1.0


def test_the_cushion_widens_by_the_estimates_position_std() -> None:
    # the flight starts at the estimate, which is off the truth by about its std: default +
    # 0.1 m/s current, fuzzy PID seeds 2202/2203, flights kept rho0 + cushion by 2 cm from an
    # estimate 0.15-0.2 m off, and the hull passed 0.002-0.08 m inside rho0
    gap = CFG.rho0_m + CFG.tuning.rollout_cushion_m + 0.1
    req = _request(circles=(_circle_left_of_the_line(gap),))
    sure = rollout_clearance(_straight(20.0), req, _flight(), CFG)
    assert sure.short_m <= 0.0
    assert sure.keep_m == pytest.approx(CFG.rho0_m + CFG.tuning.rollout_cushion_m)
    doubtful = rollout_clearance(_straight(20.0), req, _flight(start_std_m=0.2), CFG)
    sigmas = CFG.tuning.rollout_start_sigmas
    assert doubtful.keep_m == pytest.approx(sure.keep_m + sigmas * 0.2)
    assert doubtful.short_m > 0.0


def test_a_turn_first_from_outside_the_margin_whose_arc_keeps_it_keeps_the_cushion() -> None:
    # default + 0.1 m/s current, fuzzy PID seed 2203: a turn first from 4 m clear kept the
    # margin, but its flight was held to rho0 alone for R_min past the arc (as if settling
    # from an escape), passed rho0 by 0.12 m, and the hull came 0.08 m inside it
    circle = _circle_left_of_the_line(CFG.rho0_m + 0.05, x=9.0)
    req = _request(circles=(circle,))
    turned = dataclasses.replace(_straight(20.0), escape_m=2.0, turn_rad=-0.26)
    f = rollout_clearance(turned, req, _flight(), CFG)
    assert f.keep_m == pytest.approx(CFG.rho0_m + CFG.tuning.rollout_cushion_m)
    assert f.short_m > 0.0


def test_a_turn_first_from_outside_the_margin_is_held_to_its_own_depth() -> None:
    # seed 1504 in a current: a turn-first arc from 5 m clear was spared over its whole 11 m,
    # its flight passed 0.27 m from the obstacle its own arc passed at 0.8 m
    circle = _circle_left_of_the_line(0.2, x=12.0)  # 7 m on; the start is well clear
    req = _request(circles=(circle,))
    shallow = dataclasses.replace(_straight(20.0), escape_m=10.0, margin_entered_m=0.1)
    f = rollout_clearance(shallow, req, _flight(), CFG)
    assert f.min_clearance_m < 0.25
    assert f.keep_m == pytest.approx(CFG.rho0_m - 0.1 - CFG.tuning.rollout_cushion_m)
    assert f.short_m > 0.0
    # an arc planned that deep into the margin is flown as deep
    deep = dataclasses.replace(shallow, margin_entered_m=0.9)
    assert rollout_clearance(deep, req, _flight(), CFG).short_m <= 0.0


def test_a_plan_is_flown_in_the_stronger_current_the_estimate_may_settle_to() -> None:
    # the obstacle clears the path by rho0 + 0.3 m; the controller believes still water, and a
    # 0.3 m/s current towards the obstacle, if it is there, carries the flight inside rho0
    gap = CFG.rho0_m + 0.3
    req = _request(circles=(_circle_left_of_the_line(gap, x=30.0),))
    calm = _flight()
    assert rollout_clearance(_straight(20.0), req, calm, CFG).short_m <= 0.0
    doubted = dataclasses.replace(calm, doubt=calm.model.with_current(0.0, 0.3))
    f = rollout_clearance(_straight(20.0), req, doubted, CFG)
    assert f.short_m > 0.0 and f.min_clearance_m < gap - 0.1


class _Planner:
    """A stand-in for plan_path: a straight path farther from y = 20 the wider the margin
    asked, or NO_PATH from the second call on (`fail_again`), but for a request with a disc
    more than the scenario's: then, with `detour`, a path 5 m to the side; and, with
    `slow_ok`, for a request slower than the first: the first's path; records the configs
    and requests asked."""

    def __init__(
        self, *, fail_again: bool = False, detour: bool = False, slow_ok: bool = False
    ) -> None:
        self.asked: list[PlannerConfig] = []
        self.requests: list[PlanRequest] = []
        self.fail_again = fail_again
        self.detour = detour
        self.slow_ok = slow_ok

    def __call__(self, req: PlanRequest, cfg: PlannerConfig) -> PlanResult:
        self.asked.append(cfg)
        self.requests.append(req)
        if self.detour and len(req.obstacles.circles) > len(self.requests[0].obstacles.circles):
            return _straight(15.0)
        if self.slow_ok and req.v_ref_mps < self.requests[0].v_ref_mps:
            return _straight(20.0)
        if self.fail_again and len(self.asked) > 1:
            return PlanResult(status="NO_PATH", reason="no feasible curve", strategy="no_curve")
        return _straight(20.0 - 4.0 * (cfg.clearance_margin_m - CFG.clearance_margin_m))


def test_a_plan_whose_flight_keeps_rho0_is_adopted_as_made() -> None:
    planner = _Planner()
    req = _request(circles=(_circle_left_of_the_line(CFG.rho0_m + 0.3),))
    first = planner(req, CFG)
    got = plan_and_verify(req, CFG, _flight(), planner)
    assert (
        len(planner.asked) == 2
        and got.reason == ""
        and np.array_equal(got.control_points, first.control_points)
    )
    assert (got.flown_short_m, got.flown_short_at_s) == (0.0, math.inf)


def test_a_plan_flown_inside_rho0_is_made_again_wider_and_says_so() -> None:
    planner = _Planner()
    req = _request(circles=(_circle_left_of_the_line(CFG.rho0_m + 0.12, x=9.0),))
    got = plan_and_verify(req, CFG, _flight(w0=W_MAX), planner)
    first, wider = planner.asked
    assert first is CFG
    # the margin asked is the tracking error the first flight showed, plus the cushion
    flown = rollout_clearance(_straight(20.0), req, _flight(w0=W_MAX), CFG)
    assert flown.min_clearance_m < CFG.rho0_m + CFG.tuning.rollout_cushion_m
    assert math.isclose(wider.clearance_margin_m, flown.off_path_m + CFG.tuning.rollout_cushion_m)
    assert wider.clearance_margin_m > CFG.clearance_margin_m
    assert math.isclose(
        wider.curvature_margin, CFG.curvature_margin * CFG.tuning.rollout_curvature_factor
    )
    assert got.ok and got.control_points[0, 1] < 20.0  # the wider one
    assert "made again with a" in got.reason and "off the path" in got.reason
    assert (got.strategy, got.rejected) == ("remade_wider", ("searched",))
    again = rollout_clearance(got, req, _flight(w0=W_MAX), CFG)
    assert again.min_clearance_m >= CFG.rho0_m + CFG.tuning.rollout_cushion_m


def test_when_the_wider_plan_fails_the_first_is_kept_and_the_reason_says_why() -> None:
    planner = _Planner(fail_again=True)
    req = _request(circles=(_circle_left_of_the_line(CFG.rho0_m + 0.12, x=9.0),))
    got = plan_and_verify(req, CFG, _flight(w0=W_MAX), planner)
    assert len(planner.asked) == 4  # wider, around a disc where it came nearest, slower
    assert got.ok and got.control_points[0, 1] == 20.0
    assert "fared no better" in got.reason
    assert got.strategy == "searched"  # the first, after each way it was made again
    assert got.rejected == ("remade_wider", "remade_around", "remade_slower")
    # ... and it carries how far and when its flight first falls short (decline.py)
    flown = rollout_clearance(got, req, _flight(w0=W_MAX), CFG)
    assert got.flown_short_m == pytest.approx(flown.short_m) and got.flown_short_m > 0.0
    assert 0.0 < got.flown_short_at_s <= flown.t_s


def test_a_bend_flown_wide_at_any_margin_is_made_again_slower_and_flown_at_that_speed() -> None:
    # turning hard the other way as it starts, the vehicle runs the start of its path wide at
    # cruise speed (no wider plan is found here); slower, its yaw lag costs less of the path
    planner = _Planner(fail_again=True, slow_ok=True)
    req = _request(circles=(_circle_left_of_the_line(CFG.rho0_m + 0.17, x=9.0),))
    keep = CFG.rho0_m + CFG.tuning.rollout_cushion_m
    at_cruise = rollout_clearance(_straight(20.0), req, _flight(w0=W_MAX), CFG)
    assert at_cruise.min_clearance_m < keep
    got = plan_and_verify(req, CFG, _flight(w0=W_MAX), planner)
    slower = planner.requests[-1]
    assert math.isclose(slower.v_ref_mps, V * CFG.tuning.rollout_slow_factor)
    assert planner.asked[-1] is CFG  # the margins as asked: only the speed differs
    assert got.ok and got.v_ref_mps == slower.v_ref_mps  # the speed it is to be followed at
    assert f"made again for {slower.v_ref_mps:.2f} m/s" in got.reason
    flown = rollout_clearance(got, slower, _flight(w0=W_MAX), CFG)
    assert flown.off_path_m < at_cruise.off_path_m and flown.min_clearance_m >= keep
    # ... until a turning radius past where its flight came nearest, then at cruise again
    assert got.slow_until_m == pytest.approx(flown.path_s_m + req.r_min_m)
    assert 0.0 < got.slow_until_m < got.length_m
    # a plan that flies clear at cruise speed is kept at it
    clear = plan_and_verify(_request(), CFG, _flight(), _Planner())
    assert clear.ok and clear.v_ref_mps is None


def test_a_squeeze_too_narrow_for_the_wider_margin_is_left_for_another_way() -> None:
    planner = _Planner(fail_again=True, detour=True)
    circle = _circle_left_of_the_line(CFG.rho0_m + 0.12, x=9.0)
    req = _request(circles=(circle,))
    got = plan_and_verify(req, CFG, _flight(w0=W_MAX), planner)
    first, wider, around = planner.requests
    assert first is req and wider is req
    (disc,) = set(around.obstacles.circles) - {circle}
    flown = rollout_clearance(_straight(20.0), req, _flight(w0=W_MAX), CFG)
    assert (disc.x_m, disc.y_m) == (flown.x, flown.y) and disc.id != circle.id
    assert planner.asked[2] is CFG
    assert got.ok and got.control_points[0, 1] == 15.0
    assert "made again around where it came nearest" in got.reason


def test_neither_a_detour_nor_slower_round_a_moving_obstacle_it_will_be_elsewhere() -> None:
    # the mover crosses just ahead of the vehicle: its flight comes near it, not near a wall
    mover = ObstacleState(
        id=9, x=12.0, y=20.0 + R + 1.05 + 1.0 + 4.0, vx=0.0, vy=-1.0, ax=0.0, ay=0.0,
        radius=1.0, moving=True,
    )  # fmt: skip
    planner = _Planner(fail_again=True, detour=True)
    req = _request(moving=[mover])
    flown = rollout_clearance(_straight(20.0), req, _flight(), CFG)
    assert not flown.static and flown.min_clearance_m < CFG.rho0_m + CFG.tuning.rollout_cushion_m
    plan_and_verify(req, CFG, _flight(), planner)
    assert len(planner.asked) == 2  # wider only: slower would meet it at another time


def test_no_path_is_not_flown() -> None:
    def nothing(req: PlanRequest, cfg: PlannerConfig) -> PlanResult:
        return PlanResult(status="NO_PATH", reason="walled off", strategy="no_route")

    got = plan_and_verify(_request(), CFG, _flight(), nothing)
    assert not got.ok and got.reason == "walled off"


@pytest.mark.parametrize("past_m", [1.5, 2.0 * SCENARIO.vehicle.turn_radius_min_m])
def test_just_after_an_escape_the_flight_is_held_to_rho0_without_the_cushion(
    past_m: float,
) -> None:
    # an escape ends at rho0 + 1 cm and the plan leaves the margin gradually after it: for a
    # turning radius rho0 alone is kept; an obstacle passed farther on gets the cushion too
    # (fleet4 seed 64: held to rho0 alone all along, a flight past its escape cleared it by 8 mm,
    # was adopted as made, and the vehicle passed 0.05 m inside it)
    escape_m = 2.0
    circle = _circle_left_of_the_line(CFG.rho0_m + 0.05, x=5.0 + escape_m + past_m)
    # the escape starts inside the margin: an obstacle beside the start, on the right
    beside = dataclasses.replace(_circle_left_of_the_line(CFG.rho0_m + 0.1, x=5.0), id=2)
    beside = dataclasses.replace(beside, y_m=40.0 - beside.y_m)
    req = _request(circles=(circle, beside))
    escaping = dataclasses.replace(_straight(20.0, x1=40.0), escape_m=escape_m)
    planner = _Planner()

    def escape_first(q: PlanRequest, c: PlannerConfig) -> PlanResult:
        planner(q, c)  # counted
        return escaping if len(planner.asked) == 1 else _straight(19.0, x1=40.0)

    flown = rollout_clearance(escaping, req, _flight(), CFG)
    assert CFG.rho0_m < flown.min_clearance_m < CFG.rho0_m + CFG.tuning.rollout_cushion_m
    got = plan_and_verify(req, CFG, _flight(), escape_first)
    if past_m < SCENARIO.vehicle.turn_radius_min_m:
        assert flown.short_m <= 0.0 and flown.keep_m == CFG.rho0_m
        assert len(planner.asked) == 1 and got is escaping
    else:
        assert flown.short_m > 0.0 and flown.keep_m == CFG.rho0_m + CFG.tuning.rollout_cushion_m
        assert len(planner.asked) > 1 and got.control_points[0, 1] == 19.0
        assert "made again with a" in got.reason
    plain = plan_and_verify(req, CFG, _flight(), _Planner())
    assert "flown on the response model" in plain.reason  # without an escape: the cushion


def test_a_plan_whose_own_rollout_touches_an_obstacle_is_never_handed_back(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # issue 61: a planner woken from an 8 s SIGSTOP adopted a plan made again that "fared no
    # better" (its rollout had the hull at -0.38 m) and flew it into contact. Whatever the
    # planning gives, a plan whose rollout touches an obstacle is replaced by a way aside that
    # keeps clear, or by NO_PATH (hold)
    from services.planner import asking

    through = _straight(20.0)  # straight through the circle at (30, 20)
    monkeypatch.setattr(asking, "_plan_over_ground", lambda *a, **k: through)
    req = _request(circles=(CircleObstacleConfig(id=1, x_m=30.0, y_m=20.0, radius_m=3.0),))
    fm = _flight()
    got = asking.plan_clear_of_contact(_ask(req, CFG, fm))
    assert got is not through
    assert "would touch an obstacle" in got.reason, got.reason
    if got.ok:
        assert rollout_clearance(got, req, fm, CFG).min_clearance_m >= 0.0
        assert (got.strategy, got.rejected) == ("stepped_aside", through.tried)
    else:
        assert got.status == "NO_PATH" and got.reason.endswith("holds")
        assert got.strategy == "declined_contact" and got.rejected[0] == "searched"
    # a plan clear of contact is handed back as it is
    clear = _straight(5.0)
    monkeypatch.setattr(asking, "_plan_over_ground", lambda *a, **k: clear)
    assert asking.plan_clear_of_contact(_ask(req, CFG, fm)) is clear


def test_contact_beyond_the_horizon_does_not_hold_the_vehicle_at_its_start(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # issue 60: in a current, a first plan's rollout guessed contact ~60 s on, near the goal;
    # refused at every replan, the vehicle kept station at its start for the whole run. Only
    # contact within contact_horizon_s refuses a plan: the replans on the way judge the rest
    from services.planner import asking

    through = _straight(20.0)  # reaches the circle at x = 30 - 3 - R, ~15 s on at cruise
    monkeypatch.setattr(asking, "_plan_over_ground", lambda *a, **k: through)
    req = _request(circles=(CircleObstacleConfig(id=1, x_m=30.0, y_m=20.0, radius_m=3.0),))
    fm = _flight()
    reach_s = rollout_clearance(through, req, fm, CFG).t_s
    assert 5.0 < reach_s < 25.0
    near = dataclasses.replace(CFG.tuning, contact_horizon_s=reach_s + 5.0)
    far = dataclasses.replace(CFG.tuning, contact_horizon_s=reach_s - 5.0)
    held = asking.plan_clear_of_contact(_ask(req, dataclasses.replace(CFG, tuning=near), fm))
    assert held is not through
    kept = asking.plan_clear_of_contact(_ask(req, dataclasses.replace(CFG, tuning=far), fm))
    assert kept is through
    within = rollout_clearance(through, req, fm, CFG, within_s=reach_s - 5.0)
    assert within.min_clearance_m > 0.0 and within.t_s <= reach_s - 5.0


def _hook() -> PlanResult:
    """An OK plan to the goal (60, 20) whose last bend no controller follows: it comes down on
    the goal from (60, 25), and its rollout passes the goal metres off."""
    ctrl = np.array([(5, 20), (20, 20), (40, 20), (54, 20), (57, 25), (60, 25), (60, 20)], float)
    return _plan_through(ctrl, 62.0)


def test_a_plan_whose_rollout_misses_the_goal_is_made_again_until_one_arrives() -> None:
    req = dataclasses.replace(_request(), goal_tolerance_m=1.5)
    made: list[tuple[PlanRequest, PlannerConfig]] = []

    def plan(q: PlanRequest, c: PlannerConfig) -> PlanResult:
        made.append((q, c))
        return _hook() if len(made) == 1 else _straight(20.0, 5.0, 60.0)

    got = plan_and_verify(req, CFG, _flight(), plan)
    assert got.strategy == "remade_wider" and "passed the goal" in got.reason, got.reason
    assert made[1][1].curvature_margin < CFG.curvature_margin  # gentler bends asked
    # without a tolerance, or when no plan made again arrives, the first plan stands
    made.clear()
    assert plan_and_verify(_request(), CFG, _flight(), plan).control_points.shape == (7, 2)
    made.clear()
    first = plan_and_verify(req, CFG, _flight(), lambda q, c: _hook())
    assert first.strategy == "searched" and first.rejected == ("remade_wider", "remade_slower")
