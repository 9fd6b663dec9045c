"""Stepping aside (services/planner/evade.py): a vehicle with no plan to its goal, held in a
moving obstacle's way, takes a way aside that its flight shows clears more."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from common.config.scenario import load_scenario
from common.world import ObstacleState
from services.planner.controllers import Limits, make_controller
from services.planner.evade import EVADE_S, GAIN_M, plan_or_step_aside, step_aside
from services.planner.flight import FlightModel, flown
from services.planner.plan import Obstacles, PlanRequest, Pose2D
from services.planner.response import ResponseModel

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
SCENARIO = load_scenario(DEFAULT)[0]
CFG = SCENARIO.planner
R = SCENARIO.vehicle.radius_m
V = SCENARIO.vehicle.cruise_speed_mps


def _head_on(x: float = 16.0, vx: float = -0.8) -> ObstacleState:
    """A moving disc on the vehicle's line (y = 20), coming at it from the east."""
    return ObstacleState(id=9, x=x, y=20.0, vx=vx, vy=0.0, ax=0.0, ay=0.0, radius=1.0, moving=True)


def _request(*moving: ObstacleState, start: Pose2D | None = None) -> PlanRequest:
    return PlanRequest(
        start=start or Pose2D(x=5.0, y=20.0, theta=0.0),
        goal=Pose2D(x=60.0, y=20.0, theta=0.0),
        area=SCENARIO.world.area,
        obstacles=Obstacles(moving=moving),
        vehicle_radius_m=R,
        r_min_m=SCENARIO.vehicle.turn_radius_min_m,
        v_ref_mps=V,
    )


def _flight(start: tuple[float, float, float, float, float] = (5.0, 20.0, 0.0, V, 0.0)):
    limits = Limits.from_vehicle(SCENARIO.vehicle, yaw_lag_lead=True)
    return FlightModel(
        controller=make_controller(SCENARIO.controller, limits),
        model=ResponseModel.from_vehicle(SCENARIO.vehicle),
        step_s=CFG.period_s,
        start=start,
        t0=0.0,
    )


def _held_clearance(req: PlanRequest, fm: FlightModel) -> float:
    """The least hull gap to the obstacle of a vehicle that stops (as core.py stops it)."""
    pose, worst = fm.start, np.inf
    for k in range(round(EVADE_S / fm.step_s) + 1):
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
    assert way.min_clearance_m >= held + GAIN_M and way.min_clearance_m > 0.0
    assert abs(way.turn_rad) > 0.0 and "steps aside" in way.reason
    # the way is an exact drivable arc (no tighter than R_min), swept clear of contact
    assert way.max_curvature <= 1.0 / SCENARIO.vehicle.turn_radius_min_m + 1e-9
    assert way.escape_m == way.length_m
    # flown, it never touches the obstacle where it will be
    f = flown(way, req, fm)
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
    # what a new one must beat (by GAIN_M), not holding
    f = flown(way, req, fm)
    k = round(1.0 / fm.step_s)
    x, y = f.pts[k]
    dx, dy = f.pts[k + 1] - f.pts[k]
    th = float(np.arctan2(dy, dx))
    on = _request(_head_on().advanced(1.0), start=Pose2D(x=float(x), y=float(y), theta=th))
    fm_on = _flight((float(x), float(y), th, float(np.hypot(dx, dy)) / fm.step_s, 0.0))
    assert step_aside(on, CFG, fm_on, aside=None) is not None  # holding there: still in the way
    assert step_aside(on, CFG, fm_on, aside=way) is None  # going on along it: as good as any
