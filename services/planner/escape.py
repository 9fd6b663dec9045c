"""Escape: the shortest straight way out for a start in contact, off the area or in the margin.

A plan starts at the vehicle. When that pose already touches an obstacle (eq. (12): the
centre-to-surface distance d is <= the hull radius r), the grid has no free start cell, and
the pipeline answered NO_PATH at every replan while the vehicle sat in contact, v = 0, for
the rest of the run. So the planner first leaves contact by the shortest way out, then plans
the rest from the free pose it reaches (plan.py), and the path is the two joined.

The way out is a straight segment from the start, in one of `N_DIRECTIONS` directions:
- it must never take the hull deeper (d along it stays >= d at the start, or >= r + rho0
  from a start that far out) and must keep it in the area (eq. (10)), or, from a start the
  vehicle coasted out of the area to, bring it back in;
- it ends where d first reaches r + rho0 + 1 cm: out of the safety margin of eq. (12)-(13),
  so the rest is an ordinary plan. In a gap too narrow for that, it ends at r + rho0 / 4 +
  1 cm instead (the hull free; the rest then leaves the margin like any start inside it);
- the segment along the current heading needs no turn, so it keeps R_min (eqs. (19)-(20))
  and is taken whenever it gets out. Otherwise the vehicle turns on the spot first (v = 0,
  a yaw rate within eq. (11)): with no reverse (v_min >= 0), every forward arc of radius
  >= R_min from a pose that heads into the obstacle first drives the hull deeper. Among
  those, the cheapest by length + R_min |turn| wins (the turn costed as the arc an R_min
  turn would take: its time at cruise speed), ties to the smaller turn. When no plan can
  be made from where it ends (it faces a wall, say), the next best is tried.
For a convex obstacle the distance is convex along a line: the direction of the outward
normal is the shortest way out, and a direction that does not start inwards never goes
deeper. Moving obstacles are compared where they will be when the vehicle passes, after the
turn (turn time R_min |turn| / v_ref: an R_min turn's yaw rate, within eq. (11) by config).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from common.config.world import AreaConfig
from common.scalar import wrap_angle
from common.world import ObstacleState
from common.world.geometry import FloatArray
from services.planner.clearance import StaticField, moving_distance
from services.planner.nurbs_curve import NurbsCurve, join
from services.planner.result import PlanResult, Pose2D

N_DIRECTIONS = 72  # every 5 degrees: the normal is missed by at most 2.5 degrees (cos > 0.999)
STEP_M = 0.05  # sampling step along each candidate segment
BEYOND_M = 0.01  # end this far past the target clearance, so the free pose is strictly free
MAX_ESCAPES = 8  # ways out tried in turn when no plan can be made from where one ends
SPREAD_RAD = math.radians(30.0)  # ... in directions this far apart, so each tries a new place


@dataclass(frozen=True, kw_only=True)
class Escape:
    """A way out of contact: turn on the spot by `turn_rad`, then run straight `length_m`."""

    start: Pose2D
    turn_rad: float  # signed (> 0 to the left); 0 when leaving along the current heading
    length_m: float
    start_clearance_m: float  # hull to surface at the start (<= 0: in contact)
    end_clearance_m: float  # hull to surface at the free pose (> 0)
    start_outside_m: float = 0.0  # how far the hull reaches beyond the area's edge (eq. (10))

    @property
    def heading(self) -> float:
        return wrap_angle(self.start.theta + self.turn_rad)

    @property
    def free(self) -> Pose2D:
        """Where the escape ends, heading along it: the start of the rest of the plan."""
        h = self.heading
        return Pose2D(
            x=self.start.x + self.length_m * math.cos(h),
            y=self.start.y + self.length_m * math.sin(h),
            theta=h,
        )

    def duration_s(self, r_min_m: float, v_ref_mps: float) -> float:
        """Time to run it at cruise speed, the turn at an R_min turn's yaw rate v_ref / R_min."""
        return (r_min_m * abs(self.turn_rad) + self.length_m) / v_ref_mps

    def describe(self) -> str:
        turn = (
            "straight ahead"
            if self.turn_rad == 0.0
            else f"after turning {math.degrees(self.turn_rad):+.0f} deg on the spot"
        )
        if self.start_outside_m > 0.0:
            where = f"outside the area (hull {self.start_outside_m:.2f} m beyond its edge)"
        elif self.start_clearance_m <= 0.0:
            where = f"in contact (hull clearance {self.start_clearance_m:.2f} m)"
        else:
            where = f"inside the safety margin (hull clearance {self.start_clearance_m:.2f} m)"
        return (
            f"start {where}: escape {self.length_m:.2f} m {turn} to a hull clearance of "
            f"{self.end_clearance_m:.2f} m"
        )


def find_escapes(
    start: Pose2D,
    static: StaticField,
    moving: tuple[ObstacleState, ...],
    area: AreaConfig,
    *,
    r: float,
    rho0: float,
    r_min: float,
    v_ref: float,
    accel_horizon_s: float,
    max_len_m: float,
) -> list[Escape]:
    """Ways out as in the module docstring, best first; empty if none within max_len_m.

    Distances d are centre to surface (m); `r` is the hull radius, `rho0` the safe distance.
    The best is the one to take; the others (at most MAX_ESCAPES in all, directions at
    least SPREAD_RAD apart) are for when no plan can be made from where the best one ends.
    """
    turns = (np.arange(N_DIRECTIONS) * math.tau / N_DIRECTIONS + math.pi) % math.tau - math.pi
    s = np.arange(0.0, max_len_m + STEP_M, STEP_M)  # (K,) arc length along each segment
    heading = start.theta + turns  # (J,)
    pts = np.stack(
        [
            start.x + s[None, :] * np.cos(heading)[:, None],
            start.y + s[None, :] * np.sin(heading)[:, None],
        ],
        axis=-1,
    )  # (J, K, 2)
    t_pass = (r_min * np.abs(turns)[:, None] + s[None, :]) / v_ref  # (J, K) when it gets there
    flat = pts.reshape(-1, 2)
    d = np.minimum(
        static.distance(flat)[0],
        moving_distance(moving, flat, t_pass.ravel(), accel_horizon_s)[0],
    ).reshape(pts.shape[:2])
    here = np.array([[start.x, start.y]])
    d0 = min(
        float(static.distance(here)[0][0]),
        float(moving_distance(moving, here, np.zeros(1), accel_horizon_s)[0][0]),
    )
    a = _to_edge(area, pts[..., 0], pts[..., 1])  # (J, K)
    a0 = float(_to_edge(area, np.array(start.x), np.array(start.y)))
    # a sample is usable while every sample up to it is no deeper than d0 (no nearer than
    # r + rho0, from a start beyond it) and keeps the hull in the area (eq. (10)); from a
    # start outside the area, no farther out than a0
    usable = (d >= min(d0, r + rho0) - 1e-9) & (a >= min(a0, r) - 1e-9)
    ok = np.logical_and.accumulate(usable, axis=1)
    out: list[Escape] = []
    for target in dict.fromkeys((r + rho0 + BEYOND_M, r + 0.25 * rho0 + BEYOND_M)):
        if target <= d0 + BEYOND_M and a0 >= r + BEYOND_M:
            continue  # already that far out: nothing to escape to
        reached = ok & (d >= target) & (a >= r + BEYOND_M)
        # at least one step: a moving obstacle may have drawn off during the turn, but a way
        # out is a segment (the join needs one, and the vehicle is where it was)
        reached[:, 0] = False
        hit: NDArray[np.bool_] = np.any(reached, axis=1)
        k = np.argmax(reached, axis=1)  # first sample at the target, per direction
        cost = s[k] + r_min * np.abs(turns)
        # turns[0] == 0, along the current heading: no turn, R_min kept; taken if it gets out
        order = sorted(np.flatnonzero(hit), key=lambda i: (i != 0, cost[i], abs(turns[i]), i))
        for j in order:
            if len(out) == MAX_ESCAPES:
                return out
            if any(abs(wrap_angle(e.turn_rad - turns[j])) < SPREAD_RAD for e in out):
                continue
            out.append(
                Escape(
                    start=start,
                    turn_rad=float(turns[j]),
                    length_m=float(s[k[j]]),
                    start_clearance_m=d0 - r,
                    end_clearance_m=float(d[j, k[j]]) - r,
                    start_outside_m=max(0.0, r - a0),
                )
            )
    return out


def _to_edge(area: AreaConfig, x: FloatArray, y: FloatArray) -> FloatArray:
    """Distance from points to the nearest edge of the area, negative outside it."""
    return np.minimum(
        np.minimum(x - area.x_min_m, area.x_max_m - x),
        np.minimum(y - area.y_min_m, area.y_max_m - y),
    )


def prepend_escape(esc: Escape, rest: PlanResult, goal: Pose2D) -> PlanResult:
    """The plan from the start: the escape segment, then the rest planned from `esc.free`.

    The segment is a degree-p curve with its control points evenly spaced on the line, so it
    is the straight line itself (curvature 0); the rest leaves the free pose along the
    segment's heading (eq. (10) boundary constraint), so the join is G1. Each piece gets a
    share of the parameter proportional to its length, so the parameter speed barely jumps.
    """
    if not rest.ok:
        return dataclasses.replace(rest, reason=f"{esc.describe()}; from there, {rest.reason}")
    tail = rest.curve()
    p = tail.degree
    a = np.array([esc.start.x, esc.start.y])
    line = NurbsCurve(
        p,
        np.linspace(a, tail.ctrl[0], p + 1),
        np.ones(p + 1),
        np.concatenate([np.zeros(p + 1), np.ones(p + 1)]),
    )
    total = esc.length_m + rest.length_m
    curve = join(line, tail, esc.length_m / total)
    return dataclasses.replace(
        rest,
        reason=esc.describe(),
        control_points=curve.ctrl,
        weights=curve.weights,
        knots=curve.knots,
        grid_path=np.concatenate([a[None, :], rest.grid_path]),
        length_m=total,
        f_l=total / max(math.hypot(goal.x - a[0], goal.y - a[1]), 1e-9),
        min_clearance_m=min(esc.start_clearance_m, rest.min_clearance_m),
        escape_m=esc.length_m + rest.escape_m,
        turn_rad=esc.turn_rad,
    )
