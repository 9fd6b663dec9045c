"""Stepping aside (services/planner/evade.py): a vehicle with no plan to its goal, held in a
moving obstacle's way (or where it could no longer turn about outside rho0), takes a way aside
that its flight shows clears more; a recovery into rho0 waits while holding keeps out of it."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers.planner_world import circle, default_scenario

from common.world import ObstacleState
from services.control.command.response import ResponseModel
from services.control.controllers import Limits, make_controller
from services.planner import evade
from services.planner.evade import (
    plan_or_step_aside,
    step_aside,
)
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D, plan_path
from services.planner.safety.rollout import RolloutInputs, roll_out

SCENARIO = default_scenario()
CFG = SCENARIO.planner
R = SCENARIO.vehicle.radius_m
V = SCENARIO.vehicle.cruise_speed_mps


def _head_on(x: float = 16.0, vx: float = -0.8) -> ObstacleState:
    """A moving disc on the vehicle's line (y = 20), coming at it from the east."""
    return ObstacleState(id=9, x=x, y=20.0, vx=vx, vy=0.0, ax=0.0, ay=0.0, radius=1.0, moving=True)


def _request(
    *moving: ObstacleState, start: Pose2D | None = None, static: Obstacles | None = None
) -> PlanRequest:
    return PlanRequest(
        start=start or Pose2D(x=5.0, y=20.0, theta=0.0),
        goal=Pose2D(x=60.0, y=20.0, theta=0.0),
        area=SCENARIO.world.area,
        obstacles=dataclasses.replace(static or Obstacles(), moving=moving),
        vehicle_radius_m=R,
        r_min_m=SCENARIO.vehicle.turn_radius_min_m,
        v_ref_mps=V,
    )


def _flight(start: tuple[float, float, float, float, float] = (5.0, 20.0, 0.0, V, 0.0)):
    limits = Limits.from_vehicle(SCENARIO.vehicle, yaw_lag_lead=True)
    return RolloutInputs(
        controller=make_controller(SCENARIO.controller, limits),
        model=ResponseModel.from_vehicle(SCENARIO.vehicle),
        step_s=CFG.period_s,
        start=start,
        t0=0.0,
    )


def _held_clearance(req: PlanRequest, fm: RolloutInputs) -> float:
    """The least hull gap to the obstacle of a vehicle that stops (as core.py stops it)."""
    pose, worst = fm.start, np.inf
    for k in range(round(CFG.tuning.evade_s / fm.step_s) + 1):
        (c,) = req.obstacles.moving[0].centre_at(np.array([k * fm.step_s]), CFG.accel_horizon_s)
        worst = min(worst, float(np.hypot(pose[0] - c[0], pose[1] - c[1])) - 1.0 - R)
        pose = fm.model.advance(pose, 0.0, 0.0, fm.step_s)
    return worst


def test_held_in_a_moving_obstacles_way_it_steps_aside() -> None:
    req, fm = _request(_head_on()), _flight()
    held = _held_clearance(req, fm)
    assert held < 0.0  # braking on its heading, the vehicle would be hit
    way = step_aside(req, CFG, fm)
    assert way is not None and way.ok and way.short_of_goal
    assert way.min_clearance_m >= held + CFG.tuning.evade_gain_m and way.min_clearance_m > 0.0
    assert abs(way.turn_rad) > 0.0 and "steps aside" in way.reason
    assert way.strategy == "stepped_aside"
    # the way is an exact drivable arc (no tighter than R_min), swept clear of contact
    assert way.max_curvature <= 1.0 / SCENARIO.vehicle.turn_radius_min_m + 1e-9
    assert way.escape_m == way.length_m
    # flown, it never touches the obstacle where it will be
    f = roll_out(way, req, fm, CFG.tuning)
    centres = req.obstacles.moving[0].centre_at(f.t, CFG.accel_horizon_s)
    assert np.min(np.hypot(*(f.pts - centres).T)) - 1.0 - R > 0.0


def test_without_a_threat_it_holds() -> None:
    # no moving obstacle, or one moving away: the NO_PATH stands (the vehicle stops)
    assert step_aside(_request(), CFG, _flight()) is None
    assert step_aside(_request(_head_on(x=20.0, vx=+0.8)), CFG, _flight()) is None


def test_a_plan_to_the_goal_comes_first() -> None:
    # far enough ahead to plan round: the ordinary plan, not a way aside
    got = plan_or_step_aside(_request(_head_on(x=40.0, vx=-0.3)), CFG, _flight())
    assert got.ok and not got.short_of_goal


def test_a_way_aside_in_force_is_kept_unless_another_clears_more() -> None:
    req, fm = _request(_head_on()), _flight()
    way = step_aside(req, CFG, fm)
    assert way is not None
    # one second on along it, the obstacle where it then is: going on along the way aside is
    # what a new one must beat (by CFG.tuning.evade_gain_m), not holding
    f = roll_out(way, req, fm, CFG.tuning)
    k = round(1.0 / fm.step_s)
    x, y = f.pts[k]
    dx, dy = f.pts[k + 1] - f.pts[k]
    th = float(np.arctan2(dy, dx))
    on = _request(_head_on().advanced(1.0), start=Pose2D(x=float(x), y=float(y), theta=th))
    fm_on = _flight((float(x), float(y), th, float(np.hypot(dx, dy)) / fm.step_s, 0.0))
    assert step_aside(on, CFG, fm_on, aside=None) is not None  # holding there: still in the way
    assert step_aside(on, CFG, fm_on, aside=way) is None  # going on along it: as good as any


def _far_away() -> ObstacleState:
    """A moving obstacle nowhere near (the fleet's case: there is always one)."""
    return ObstacleState(
        id=9, x=90.0, y=5.0, vx=0.0, vy=0.3, ax=0.0, ay=0.0, radius=1.0, moving=True
    )


def _stop(fm: RolloutInputs) -> tuple[float, float, float, float, float]:
    """Where a vehicle that holds (the stop command on the response model) comes to rest."""
    pose = fm.start
    for _ in range(round(CFG.tuning.evade_s / fm.step_s)):
        pose = fm.model.advance(pose, 0.0, 0.0, fm.step_s)
    return pose


def _room_kept(x: float, y: float, th: float, rock: tuple[float, float, float]) -> bool:
    """Whether a turning circle of 1.2 R_min to either side of (x, y, th) keeps the hull rho0
    clear of the circle `rock` (x, y, radius): an oracle apart from the planner's own."""
    radius, (cx, cy, rr) = 1.2 * SCENARIO.vehicle.turn_radius_min_m, rock
    for side in (1.0, -1.0):
        ox, oy = x - side * radius * math.sin(th), y + side * radius * math.cos(th)
        if math.hypot(ox - cx, oy - cy) - radius - rr - R >= CFG.rho0_m:
            return True
    return False


def test_holding_where_it_could_no_longer_turn_about_outside_rho0_it_steps_aside() -> None:
    # a rock dead ahead, far enough that braking stops clear of its margin, but so near
    # there that no turn about keeps rho0 (a recovery would then enter it): from here one does
    # (20 m in from the area's west edge: its turning circles keep the edge rho0 off too)
    here = Pose2D(x=20.0, y=20.0, theta=0.0)
    fm = _flight((here.x, here.y, here.theta, V, 0.0))
    sx, sy, sth = _stop(fm)[:3]
    rock = (sx + 7.0, 20.0, 4.0)
    assert rock[0] - rock[2] - sx - R >= CFG.rho0_m  # holding keeps the margin ...
    assert not _room_kept(sx, sy, sth, rock)  # ... but stops with no room to turn about
    assert _room_kept(here.x, here.y, here.theta, rock)  # where it is now it has that room
    rocks = Obstacles(circles=(circle(x=rock[0], y=rock[1], radius=rock[2], id=3),))
    req = _request(_far_away(), start=here, static=rocks)
    way = step_aside(req, CFG, fm)
    assert way is not None and way.ok and way.short_of_goal
    assert "no room to turn about outside rho0" in way.reason
    f = roll_out(way, req, fm, CFG.tuning)
    gap = np.hypot(f.pts[:, 0] - rock[0], f.pts[:, 1] - rock[1]) - rock[2] - R
    assert gap.min() >= CFG.rho0_m  # the way aside keeps the margin ...
    assert _room_kept(*f.last[:3], rock)  # ... and stops where it can turn about
    # no rock: nothing to step aside from
    assert step_aside(_request(_far_away(), start=here), CFG, fm) is None


@pytest.mark.parametrize(
    ("speed", "threat", "holds"),
    [
        pytest.param(V, None, True, id="moving on, holding keeps out of rho0: holds first"),
        pytest.param(
            0.5 * CFG.tuning.hold_first_factor * V, None, False, id="already held: recovers"
        ),
        pytest.param(V, _head_on(), False, id="holding is in a moving obstacle's way"),
    ],
)
def test_a_recovery_into_rho0_waits_while_holding_keeps_out_of_it(
    monkeypatch: pytest.MonkeyPatch, speed: float, threat: ObstacleState | None, holds: bool
) -> None:
    req = _request(threat or _far_away())
    # the plan a recovery would have made: its way out 0.3 m into rho0 (recover.py)
    made = dataclasses.replace(plan_path(req, CFG), margin_entered_m=0.3, turn_rad=0.5)
    assert made.ok

    def recovery(*_: object) -> PlanResult:
        return made

    monkeypatch.setattr(evade, "plan_and_verify", recovery)
    got = plan_or_step_aside(req, CFG, _flight((5.0, 20.0, 0.0, speed, 0.0)))
    if holds:
        assert got.status == "NO_PATH" and "0.30 m into rho0" in got.reason
        assert "holds first" in got.reason
        assert (got.strategy, got.rejected) == ("held_first", made.tried)
    else:
        assert got is made
