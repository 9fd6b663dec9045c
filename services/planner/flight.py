"""A planned path flown before it is adopted: the controller on the response model, rho0 in
execution.

The plan keeps the hull rho0 from every obstacle (eq. (12)-(13)) and its turns within R_min
(eq. (20)), but the vehicle flies it with a lag: its yaw rate follows the command with a time
constant and a rate bound, and |w| <= v / R_min leaves no room to catch up on a bend near
R_min. A replan that starts with a turn one way while the vehicle is turning the other way
(its curvature jumps at the start) is flown wide for the whole bend: measured on fleet4 seed
22 (inproc), auv3 ran 0.88 m off a bend of radius 5.4 m (R_min 5 m) and came 0.03 m inside
rho0 of a static obstacle the plan cleared by rho0 + 0.36 m.

So a plan is flown here first, as the planner's command sequences fly it (sequence.py): the
controller (a copy, reset as on adoption) commands every control period, the response model
(response.py) answers, from the state the plan starts at, twist included, for the whole path
(at most FLIGHT_MAX_S). Where the flight comes inside rho0 of an obstacle (past the stretch
the plan itself may pass nearer: escape_m), the flight's distance off the path there is the
tracking error, and the plan is made again with a clearance margin that wide plus
FLIGHT_CUSHION_M, its curvature aimed FLIGHT_CURVATURE_FACTOR lower. The plan whose flight
comes nearer to keeping rho0 is adopted (the first when the second fares no better, or fails);
either way its reason says what the flight found. Pure: the same floats in every runtime.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from common.config.planner import PlannerConfig
from services.planner.clearance import StaticField, moving_distance
from services.planner.controllers.base import Controller
from services.planner.path_arc_reference import PathArcReference
from services.planner.planned_path import PlannedPath
from services.planner.response import Pose, ResponseModel
from services.planner.result import PlanRequest, PlanResult

FLIGHT_MAX_S = 90.0  # a flight ends at the path's end, or after this long (s)
# a flight must keep rho0 + this: the model knows no current and no estimation error (on
# fleet4 seed 22 the vehicle flew 0.07 m nearer than its flight); the same cushion is added
# to the tracking error the flight showed, for the margin the plan is made again with
FLIGHT_CUSHION_M = 0.1
# moving obstacles count over the flight's first seconds only, as far ahead as a command
# sequence looks (controller.sequence.horizon_s): their prediction a minute ahead is a guess
# (the plan's own check, at v_ref, covers them; replans judge them anew as they come)
FLIGHT_MOVING_S = 10.0
FLIGHT_CURVATURE_FACTOR = 0.9  # the second plan aims its curvature this much lower
ARRIVED_M = 0.5  # a flight within this of the path's end, slower than ARRIVED_MPS, is over
ARRIVED_MPS = 0.05


@dataclass(frozen=True, kw_only=True)
class Flight:
    """How near a flown path comes to the obstacles: the least hull clearance (m) past the
    escape stretch, where and when (s after the plan's start), and how far off the path the
    flight was there (its tracking error, m)."""

    min_clearance_m: float
    x: float
    y: float
    t_s: float
    off_path_m: float


@dataclass(frozen=True, kw_only=True)
class FlightModel:
    """What a flight needs from the planner: its controller (copied at the ask: the real one
    goes on stepping), the response model, the control period, the state the plan starts at
    (x, y, theta, v, w) and the mission time then."""

    controller: Controller
    model: ResponseModel
    step_s: float
    start: Pose
    t0: float


def fly(result: PlanResult, req: PlanRequest, fm: FlightModel, accel_horizon_s: float) -> Flight:
    """Fly an OK plan (see the module docstring) and measure its clearance."""
    ref = PathArcReference(PlannedPath(result.curve()), req.v_ref_mps)
    ctrl = copy.deepcopy(fm.controller)
    ctrl.reset()  # as PlannerCore._adopt resets it for a new path
    pose = fm.start
    end = ref.point_at_s(ref.length)
    n = max(1, math.ceil(min(FLIGHT_MAX_S, 3.0 * ref.length / req.v_ref_mps) / fm.step_s))
    xs, ys, flown = [pose[0]], [pose[1]], [0.0]
    for k in range(n):
        v, w = ctrl.command(fm.t0 + k * fm.step_s, pose, ref)
        nxt = fm.model.advance(pose, v, w, fm.step_s)
        flown.append(flown[-1] + math.hypot(nxt[0] - pose[0], nxt[1] - pose[1]))
        pose = nxt
        xs.append(pose[0])
        ys.append(pose[1])
        if pose[3] < ARRIVED_MPS and math.hypot(pose[0] - end[0], pose[1] - end[1]) < ARRIVED_M:
            break
    pts = np.column_stack([xs, ys])
    t = fm.step_s * np.arange(len(pts), dtype=np.float64)
    obs = req.obstacles
    d = StaticField.build(obs.circles, obs.polygons).distance(pts)[0]
    soon = t <= FLIGHT_MOVING_S
    d[soon] = np.minimum(
        d[soon], moving_distance(obs.moving, pts[soon], t[soon], accel_horizon_s)[0]
    )
    d[np.asarray(flown) < result.escape_m] = math.inf  # the plan itself may pass nearer there
    j = int(np.argmin(d))
    x, y = float(pts[j, 0]), float(pts[j, 1])
    px, py = ref.point_at_s(ref.closest_s(x, y, None))
    return Flight(
        min_clearance_m=float(d[j]) - req.vehicle_radius_m,
        x=x,
        y=y,
        t_s=float(t[j]),
        off_path_m=math.hypot(x - px, y - py),
    )


Plan = Callable[[PlanRequest, PlannerConfig], PlanResult]


def plan_flown(req: PlanRequest, cfg: PlannerConfig, fm: FlightModel, plan: Plan) -> PlanResult:
    """`plan(req, cfg)`, flown; made again wider if its flight breaks rho0 (module docstring)."""
    first = plan(req, cfg)
    if not first.ok:
        return first
    f1 = fly(first, req, fm, cfg.accel_horizon_s)
    keep = cfg.rho0_m + FLIGHT_CUSHION_M
    if f1.min_clearance_m >= keep:
        return first
    found = (
        f"flown on the response model its hull cleared an obstacle by {f1.min_clearance_m:.2f} "
        f"m (rho0 {cfg.rho0_m:.2f} m) at ({f1.x:.1f}, {f1.y:.1f}) {f1.t_s:.1f} s on, "
        f"{f1.off_path_m:.2f} m off the path"
    )
    wider = replace(
        cfg,
        clearance_margin_m=max(cfg.clearance_margin_m, f1.off_path_m + FLIGHT_CUSHION_M),
        curvature_margin=cfg.curvature_margin * FLIGHT_CURVATURE_FACTOR,
    )
    second = plan(req, wider)
    if second.ok:
        f2 = fly(second, req, fm, cfg.accel_horizon_s)
        if f2.min_clearance_m > f1.min_clearance_m:
            kept = "keeps" if f2.min_clearance_m >= keep else "comes nearer keeping"
            return _with_reason(
                second,
                f"{found}; made again with a {wider.clearance_margin_m:.2f} m margin, "
                f"whose flight {kept} rho0 + {FLIGHT_CUSHION_M:.2f} m (least clearance "
                f"{f2.min_clearance_m:.2f} m)",
            )
    return _with_reason(first, f"{found}; made again wider, it fared no better")


def _with_reason(result: PlanResult, note: str) -> PlanResult:
    return replace(result, reason=f"{result.reason}; {note}" if result.reason else note)
