"""Recovering a plan near an obstacle, where no curve leaves the vehicle's pose as it is.

Without this, the planner answered NO_PATH at every replan and the vehicle stopped for good
(issue 14, defect 5: a silent deadlock). Two ways out, each followed by an ordinary plan
(`plan`, the pipeline of plan.py, handed in):
- turn_then_plan: the heading is what no curve can satisfy (eq. (10) with R_min, eqs.
  (19)-(20): the vehicle faces an obstacle too near to turn away from). Turn on the spot to
  the grid path's first leg, then plan from the same place.
- leave_then_plan: the start is in contact, outside the area (a vehicle that coasted out
  of it) or deep in the margin: the shortest straight way out (escape.py), then the rest
  planned from where it ends, joined to it.
The turn on the spot itself is controllers/turn_on_spot.py's, commanded by the core.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

from common.config.planner import PlannerConfig
from common.scalar import wrap_angle
from services.planner.clearance import StaticField
from services.planner.controllers.turn_on_spot import DONE_RAD
from services.planner.escape import find_escapes, prepend_escape
from services.planner.result import PlanRequest, PlanResult

Plan = Callable[[PlanRequest], PlanResult]  # the pipeline, with no further recovery


def turn_then_plan(req: PlanRequest, failed: PlanResult, plan: Plan) -> PlanResult:
    """No curve leaves along the vehicle's heading (eq. (10) with R_min, near an obstacle the
    vehicle heads for): turn on the spot to the grid path's first leg, and plan from there.

    The vehicle is commanded to stop on NO_PATH anyway; turning while it stops makes a path
    exist instead of stopping for good (the turn on the spot is turn_on_spot.py's).
    """
    lead = failed.grid_path[1] - failed.grid_path[0] if len(failed.grid_path) >= 2 else None
    if lead is None:
        return failed
    theta = math.atan2(float(lead[1]), float(lead[0]))
    turn = wrap_angle(theta - req.start.theta)
    if abs(turn) <= DONE_RAD:  # the heading is already that: turning cannot help
        return failed
    dt = req.r_min_m * abs(turn) / req.v_ref_mps  # at an R_min turn's yaw rate, as escape.py
    moving = tuple(o.advanced(dt) for o in req.obstacles.moving)
    turned = dataclasses.replace(
        req,
        start=dataclasses.replace(req.start, theta=theta),
        obstacles=dataclasses.replace(req.obstacles, moving=moving),
    )
    again = plan(turned)
    if not again.ok:
        return failed
    why = f"no curve leaves along the heading: turn {math.degrees(turn):+.0f} deg on the spot"
    return dataclasses.replace(again, reason=why, turn_rad=turn)


def leave_then_plan(
    req: PlanRequest, cfg: PlannerConfig, static: StaticField, d_start: float, plan: Plan
) -> PlanResult | None:
    """A start in contact, outside the area or deep in the margin: the shortest way out
    (escape.py) that a plan can continue from, joined to that plan; None if there is none.

    The way out may be as long as leaving the margin (and coming back into the area) along
    the normal, plus escape_len_m.
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
        r_min=req.r_min_m,
        v_ref=req.v_ref_mps,
        accel_horizon_s=cfg.accel_horizon_s,
        max_len_m=max_len,
    )
    first: PlanResult | None = None
    for esc in escapes:
        dt = esc.duration_s(req.r_min_m, req.v_ref_mps)
        moving = tuple(o.advanced(dt) for o in req.obstacles.moving)
        rest = dataclasses.replace(
            req, start=esc.free, obstacles=dataclasses.replace(req.obstacles, moving=moving)
        )
        res = prepend_escape(esc, plan(rest), req.goal)
        if res.ok:
            return res
        first = first or res
    return first
