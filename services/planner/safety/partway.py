"""Planning partway: a plan to a point along the searched route when no curve reaches the goal.

The search can find a route that no curve within R_min follows all the way (most often near
the goal, where a moving obstacle's predicted track bends the route into a hook the fixed
goal heading cannot join). Holding then, in a current, means drifting. A receding-horizon
step instead: a plan to a point part of the way along that route, its heading free, marked
short of the goal so the replan policy tries the goal again at every interval (replan.py
`aside`), by when the vehicle is nearer and the obstacle has moved on.

A goal held with its heading (eq. (10)) that the vehicle has overrun, or reached from the side
within a turn of it, has no route along which a curve joins it: the vehicle comes round for
another approach, to a point a few R_min behind the goal along its heading.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Iterator

import numpy as np

from common.world.geometry import FloatArray
from services.planner.result import PlanRequest, PlanResult, Pose2D

Plan = Callable[[PlanRequest], PlanResult]  # the pipeline, with no further recovery

# the shares of the route's length tried as the partway goal, in order: half way first
PARTWAY_SHARES = (0.5, 0.75, 0.25)
# then, for a goal held with its heading, the approach points this many R_min behind it
APPROACH_BACK_R = (2.0, 3.0)


def route_point(route: FloatArray, s_m: float) -> tuple[float, float]:
    """The point s_m (m) along a polyline route (n, 2), clamped to its ends."""
    seg = np.hypot(*np.diff(route, axis=0).T)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    s = min(max(s_m, 0.0), float(cum[-1]))
    i = min(int(np.searchsorted(cum, s, side="right")) - 1, len(seg) - 1)
    u = 0.0 if seg[i] == 0.0 else (s - cum[i]) / seg[i]
    p = route[i] + u * (route[i + 1] - route[i])
    return float(p[0]), float(p[1])


def partway_goals(req: PlanRequest, route: FloatArray) -> Iterator[tuple[float, float, str]]:
    """The partway goals in the order tried, (x, y, why): PARTWAY_SHARES of the route (n, 2)
    at least R_min from the start along it, then the approach points behind a goal held with
    its heading."""
    total = float(np.hypot(*np.diff(route, axis=0).T).sum()) if len(route) >= 2 else 0.0
    for share in PARTWAY_SHARES:
        s = share * total
        if s >= req.r_min_m:
            x, y = route_point(route, s)
            yield x, y, f"{s:.0f} of the route's {total:.0f} m"
    if req.fix_goal_heading:
        g = req.goal
        for k in APPROACH_BACK_R:
            back = k * req.r_min_m
            x, y = g.x - back * math.cos(g.theta), g.y - back * math.sin(g.theta)
            yield x, y, f"an approach {k:g} R_min behind the goal"


def plan_partway(req: PlanRequest, failed: PlanResult, plan: Plan) -> PlanResult | None:
    """A plan to the first of `partway_goals` along failed's route (its grid path) that a
    curve reaches, heading free and short of the goal; None if none is feasible."""
    for x, y, where in partway_goals(req, failed.grid_path):
        goal = Pose2D(x=x, y=y, theta=0.0)
        part = plan(dataclasses.replace(req, goal=goal, fix_goal_heading=False))
        if part.ok:
            why = f"partway to ({x:.1f}, {y:.1f}), {where}"
            part = part.after(failed.reason, why)
            return dataclasses.replace(part, short_of_goal=True, partway=True)
    return None
