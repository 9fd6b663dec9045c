"""Recovering a plan near an obstacle, where no curve leaves the vehicle's pose as it is.

Without a way out the planner would answer NO_PATH at every replan and the vehicle would stop
there for good, silently. Two ways out, each driven forward on arcs no
tighter than R_min (the vehicle can neither turn on the spot nor reverse), each followed by
an ordinary plan (`plan`, the pipeline of plan.py, handed in) joined to it:
- turn_then_plan: the heading is what no curve can satisfy (eq. (10) with R_min, eqs.
  (19)-(20): the vehicle faces an obstacle too near to turn away from within the margins the
  refinement keeps). Turn on an arc (toward the grid path's first leg if it can), then plan
  from there.
- leave_then_plan: the start is in contact, outside the area (a vehicle that coasted out
  of it) or deep in the margin: the way out escape.py finds, then the rest planned from
  where it ends.
- come_about_then_plan: nothing else works because the area's edge is in the way (a vehicle
  heading out of the area near its edge, or already outside and heading away, cannot turn
  back within R_min inside it): turn on an arc that may leave the area (the area is where
  the plans keep to, not a wall; the obstacles still count), run straight back into it,
  then plan from there. The shortest such way first.
The arcs have the radius ARC_RADIUS_FACTOR R_min: a controller that follows one keeps a
sixth of the plant's yaw-rate bound v / R_min for its feedback.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from common.config.planner import PlannerConfig
from common.config.world import AreaConfig
from common.scalar import wrap_angle
from services.planner.geometry.clearance import StaticField
from services.planner.result import PlanRequest, PlanResult, Pose2D
from services.planner.safety.escape import (
    BEYOND_M,
    DEPTH_STEP_M,
    MAX_ESCAPES,
    Escape,
    find_escapes,
    points_along,
    prepend_escape,
    sweep,
)

Plan = Callable[[PlanRequest], PlanResult]  # the pipeline, with no further recovery

MIN_TURN_RAD = 0.1  # ~6 degrees: a smaller turn cannot help the plan
TURN_STEP_RAD = math.radians(15.0)  # the turns a recovery tries, either way
ARC_RADIUS_FACTOR = 1.2  # a recovery's arcs are this much wider than R_min
COME_ABOUT_INSIDE_M = 1.0  # coming about ends with the hull this far inside the area (m)
COME_ABOUT_ROOM = 1.0  # ... or that many turning diameters further on


def turn_then_plan(
    req: PlanRequest, failed: PlanResult, plan: Plan, rho0_m: float = 0.0
) -> PlanResult:
    """No curve leaves along the vehicle's heading (eq. (10) with R_min, near an obstacle the
    vehicle heads for): turn on an arc, and plan from its end.

    The arcs tried turn by multiples of TURN_STEP_RAD either way, up to a half turn, and by
    exactly the turn onto the grid path's first leg; an arc must keep the hull free of every
    obstacle (moving ones where they will be, their acceleration held over the turn, as
    `ObstacleState.advanced` holds it) and in the area. It may pass nearer than the start,
    inside the safety margin even (the replan policy does not count its stretch: escape_m),
    the less the better: arcs that keep the margin rho0_m (never below min(start, r + rho0))
    come first, then they are tried by how much nearer than the start they take the hull (in
    steps of DEPTH_STEP_M), then by how far their end heading is from the leg's; at most
    MAX_ESCAPES of them. The plan says how far below min(start, r + rho0) its arc goes
    (`margin_entered_m`): a vehicle still under way holds first instead (evade.py).
    """
    lead = failed.grid_path[1] - failed.grid_path[0] if len(failed.grid_path) >= 2 else None
    if lead is None:
        return failed
    want = wrap_angle(math.atan2(float(lead[1]), float(lead[0])) - req.start.theta)
    turns = np.concatenate([[want], np.arange(-math.pi, math.pi + 1e-9, TURN_STEP_RAD)])
    turns = turns[np.abs(turns) > MIN_TURN_RAD]  # a smaller turn cannot help the plan
    radius, r = ARC_RADIUS_FACTOR * req.r_min_m, req.vehicle_radius_m
    sw = sweep(
        req.start,
        turns,
        radius,
        radius * math.pi,
        StaticField.build(req.obstacles.circles, req.obstacles.polygons),
        req.obstacles.moving,
        req.area,
        v_ref=req.pace_mps,
        accel_horizon_s=math.inf,
    )
    end = np.minimum(np.searchsorted(sw.s, radius * np.abs(turns)), len(sw.s) - 1)  # (J,)
    rows = np.arange(len(turns))
    free = sw.deeper(r + BEYOND_M, r)[rows, end] <= 0.0  # hull free, in the area, to the end
    # eq. (12)-(13): an arc that keeps the safety margin (never below min(start, r + rho0))
    # comes before any that enters it; a start outside the margin then stays outside
    entered = sw.deeper(r + rho0_m, r)[rows, end]
    kept = entered <= 0.0
    depth = sw.deeper(math.inf, r)[rows, end]  # how much nearer than at the start
    order = sorted(
        np.flatnonzero(free),
        key=lambda j: (
            not kept[j],
            round(depth[j] / DEPTH_STEP_M),
            abs(wrap_angle(turns[j] - want)),
            j,
        ),
    )
    for j in order[:MAX_ESCAPES]:
        turn = float(turns[j])
        esc = Escape(
            start=req.start,
            radius_m=radius,
            turn_rad=turn,
            length_m=radius * abs(turn),
            start_clearance_m=sw.d0 - r,
            end_clearance_m=float(sw.d[j, end[j]]) - r,
            deeper_m=float(entered[j]),
        )
        again = _plan_after(req, esc, plan)
        if again.ok:
            why = (
                f"no curve leaves along the heading: turn {math.degrees(turn):+.0f} deg on a "
                f"{radius:.1f} m arc first"
            )
            return dataclasses.replace(again, reason=why)
    return failed


def leave_then_plan(
    req: PlanRequest, cfg: PlannerConfig, static: StaticField, d_start: float, plan: Plan
) -> PlanResult | None:
    """A start in contact, outside the area or deep in the margin: the best way out
    (escape.py) that a plan can continue from, joined to that plan; None if there is none.

    After its arc, the way out may run as far as leaving the margin (and coming back into
    the area) along the normal, plus escape_len_m.
    Moving obstacles are planned for where they will be when the escape ends.
    """
    r, area, p = req.vehicle_radius_m, req.area, req.start
    beyond = max(area.x_min_m - p.x, p.x - area.x_max_m, area.y_min_m - p.y, p.y - area.y_max_m)
    max_len = cfg.escape_len_m + max(r + cfg.rho0_m - d_start, 0.0) + max(r + beyond, 0.0)
    escapes = find_escapes(
        req.start,
        static,
        req.obstacles.moving,
        req.area,
        r=r,
        rho0=cfg.rho0_m,
        radius_m=ARC_RADIUS_FACTOR * req.r_min_m,
        v_ref=req.pace_mps,
        accel_horizon_s=cfg.accel_horizon_s,
        max_len_m=max_len,
    )
    first: PlanResult | None = None
    for esc in escapes:
        res = _plan_after(req, esc, plan)
        if res.ok:
            return res
        first = first or res
    return first


def come_about_then_plan(req: PlanRequest, plan: Plan) -> PlanResult | None:
    """Come about (module docstring): turns by multiples of TURN_STEP_RAD either way up to a
    whole half turn, on arcs of ARC_RADIUS_FACTOR R_min, each then straight until the hull is
    COME_ABOUT_INSIDE_M inside the area (or COME_ABOUT_ROOM turning diameters further, for
    room to turn towards the goal from there); the hull must stay free of every obstacle (moving
    ones where they will be) all the way. Tried shortest first, at most MAX_ESCAPES; None if
    none is clear, else the first that a plan continues (or the first's NO_PATH)."""
    radius, r, area = ARC_RADIUS_FACTOR * req.r_min_m, req.vehicle_radius_m, req.area
    turns = np.arange(TURN_STEP_RAD, math.pi + 1e-9, TURN_STEP_RAD)
    turns = np.concatenate([turns, -turns])
    inside = r + COME_ABOUT_INSIDE_M
    runs = np.array([_run_inside(req.start, float(t), radius, area, inside) for t in turns])
    # each also runs on COME_ABOUT_ROOM turning diameters: the plan from where it ends may
    # need room to turn towards the goal (near the goal, most of all)
    turns = np.concatenate([turns, turns])
    runs = np.concatenate([runs, runs + COME_ABOUT_ROOM * 2.0 * radius])
    lengths = radius * np.abs(turns) + runs
    feasible = np.isfinite(lengths)
    if not feasible.any():
        return None
    turns, lengths = turns[feasible], lengths[feasible]
    sw = sweep(
        req.start,
        turns,
        radius,
        float(lengths.max()),
        StaticField.build(req.obstacles.circles, req.obstacles.polygons),
        req.obstacles.moving,
        area,
        v_ref=req.pace_mps,
        accel_horizon_s=math.inf,
    )
    end = np.minimum(np.searchsorted(sw.s, lengths), len(sw.s) - 1)
    rows = np.arange(len(turns))
    clear = sw.deeper(r + BEYOND_M, -math.inf)[rows, end] <= 0.0  # obstacles only
    first: PlanResult | None = None
    for j in sorted(np.flatnonzero(clear), key=lambda j: (lengths[j], abs(turns[j])))[:MAX_ESCAPES]:
        esc = Escape(
            start=req.start,
            radius_m=radius,
            turn_rad=float(turns[j]),
            length_m=float(lengths[j]),
            start_clearance_m=sw.d0 - r,
            end_clearance_m=float(sw.d[j, end[j]]) - r,
            start_outside_m=max(0.0, r - sw.a0),
        )
        again = _plan_after(req, esc, plan)
        if again.ok:
            out = float(-np.min(sw.a[j, : end[j] + 1]) + r)
            why = (
                f"no curve within the area: come about, turning "
                f"{math.degrees(esc.turn_rad):+.0f} deg on a {radius:.1f} m arc"
                + (f" (the hull up to {out:.1f} m beyond the area's edge)" if out > 0 else "")
                + " first"
            )
            return dataclasses.replace(again, reason=why)
        first = first or again
    return first


def _run_inside(start: Pose2D, turn: float, radius: float, area: AreaConfig, m: float) -> float:
    """How far to run straight after an arc turning `turn` from `start` until the point is m
    inside the area (0: already there; inf: its heading never gets it there)."""
    end = points_along(start, np.array([turn]), radius, np.array([radius * abs(turn)]))[0, 0]
    th = start.theta + turn
    c, sn = math.cos(th), math.sin(th)
    lo, hi = 0.0, math.inf
    for p, d, a, b in ((end[0], c, area.x_min_m + m, area.x_max_m - m),
                       (end[1], sn, area.y_min_m + m, area.y_max_m - m)):  # fmt: skip
        if a > b:
            return math.inf
        if abs(d) < 1e-12:
            if not a <= p <= b:
                return math.inf
            continue
        t1, t2 = (a - p) / d, (b - p) / d
        lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
    return lo if lo <= hi else math.inf


def _plan_after(req: PlanRequest, esc: Escape, plan: Plan) -> PlanResult:
    """The way out joined to the plan from where it ends (moving obstacles advanced by the
    time it takes at cruise speed)."""
    dt = esc.duration_s(req.pace_mps)
    moving = tuple(o.advanced(dt) for o in req.obstacles.moving)
    rest = dataclasses.replace(
        req, start=esc.free, obstacles=dataclasses.replace(req.obstacles, moving=moving)
    )
    return prepend_escape(esc, plan(rest), req.goal)
