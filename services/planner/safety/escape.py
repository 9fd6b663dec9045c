"""Escape: a drivable way out (R_min arcs) for a start in contact, off the area or in the margin.

A plan starts at the vehicle. When that pose already touches an obstacle (eq. (12): the
centre-to-surface distance d is <= the hull radius r), the grid has no free start cell, so no
search can start there. So the planner first leaves contact, then plans the rest from the
free pose it reaches (plan.py), and the path is the two joined.

The vehicle cannot turn on the spot (the plant enforces |w| <= v / R_min, eqs. (19)-(20))
and has no reverse (v_min >= 0), so a way out leaves along the vehicle's heading: an arc of
radius `radius_m` (no tighter than R_min; recover.py takes 1.2 R_min) turning by `turn_rad`,
then a straight run, in one of `N_TURNS` turns (straight ahead, and arcs to either side up to a
half turn). Along it:
- the hull may not go deeper into contact than it starts (d stays >= d at the start, and
  > r from a start out of contact), nor farther out of the area (eq. (10)) than it starts;
  from a vehicle that heads into an obstacle (or out of the area), every forward way out
  first goes deeper (a bow-on contact needs metres of arc to clear), and such a start stays
  NO_PATH: the vehicle stops where it is rather than ram its way through. Into the safety
  margin it may go, but the less the better (below);
- it ends where d first reaches r + rho0 + 1 cm: out of the safety margin of eq. (12)-(13),
  so the rest is an ordinary plan. In a gap too narrow for that, it ends at r + rho0 / 4 +
  1 cm instead (the hull free; the rest then leaves the margin like any start inside it).
Among the ways out, the one that goes least deep below min(d at the start, r + rho0), in
steps of `DEPTH_STEP_M`, wins, then the shortest (it gains clearance soonest), then the
smallest turn. When no plan can be made from where it ends (it faces a wall, say), the next
best is tried. Moving obstacles are compared
where they will be when the vehicle passes (arc length over the cruise speed).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np

from common.config.world import AreaConfig
from common.scalar import wrap_angle
from common.world import ObstacleState
from common.world.geometry import FloatArray
from services.planner.geometry.clearance import StaticField, moving_distance
from services.planner.geometry.nurbs_curve import NurbsCurve, join
from services.planner.result import PlanResult, Pose2D

N_TURNS = 73  # straight ahead and arcs every 5 degrees to either side, up to +-180 degrees
STEP_M = 0.05  # sampling step along each candidate
BEYOND_M = 0.01  # end this far past the target clearance, so the free pose is strictly free
MAX_ESCAPES = 8  # ways out tried in turn when no plan can be made from where one ends
SPREAD_RAD = math.radians(30.0)  # ... in end headings this far apart, so each tries a new place
DEPTH_STEP_M = 0.05  # ways out that go equally deep within this are ranked by length


@dataclass(frozen=True, kw_only=True)
class Escape:
    """A way out of contact: an arc of `radius_m` turning by `turn_rad`, then straight."""

    start: Pose2D
    radius_m: float  # of the arc (>= R_min)
    turn_rad: float  # signed heading change along the arc (> 0 to the left); 0: straight ahead
    length_m: float  # the whole way out: the arc, then the straight run
    start_clearance_m: float  # hull to surface at the start (<= 0: in contact)
    end_clearance_m: float  # hull to surface at the free pose (> 0)
    start_outside_m: float = 0.0  # how far the hull reaches beyond the area's edge (eq. (10))
    # how far the way goes below min(d at the start, r + rho0): into the margin, never into
    # contact deeper than the start
    deeper_m: float = 0.0

    @property
    def arc_m(self) -> float:
        return self.radius_m * abs(self.turn_rad)

    @property
    def heading(self) -> float:
        return wrap_angle(self.start.theta + self.turn_rad)

    @property
    def free(self) -> Pose2D:
        """Where the escape ends, heading along it: the start of the rest of the plan."""
        x, y = self.point_at(self.length_m)
        return Pose2D(x=x, y=y, theta=self.heading)

    def point_at(self, s: float) -> tuple[float, float]:
        """The point at arc length s along the way out."""
        xy = points_along(self.start, np.array([self.turn_rad]), self.radius_m, np.array([s]))
        return float(xy[0, 0, 0]), float(xy[0, 0, 1])

    def duration_s(self, v_ref_mps: float) -> float:
        """Time to run it at cruise speed."""
        return self.length_m / v_ref_mps

    def describe(self) -> str:
        turn = (
            "straight ahead"
            if self.turn_rad == 0.0
            else f"turning {math.degrees(self.turn_rad):+.0f} deg on a "
            f"{self.radius_m:.1f} m arc first"
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

    def curve(self, degree: int, end: FloatArray | None = None) -> NurbsCurve:
        """The way out as a clamped NURBS of `degree`: exact circular arcs (rational, at most
        a quarter turn each), then the straight run; `end` (2,) snaps the last point."""
        pieces: list[tuple[NurbsCurve, float]] = []
        n_arcs = math.ceil(abs(self.turn_rad) / (0.5 * math.pi) - 1e-12)
        for i in range(n_arcs):
            a0 = self.turn_rad * i / n_arcs
            a1 = self.turn_rad * (i + 1) / n_arcs
            pieces.append((self._arc_piece(a0, a1, degree), self.arc_m / n_arcs))
        straight = self.length_m - self.arc_m
        if straight > 1e-9 or not pieces:
            a = np.array(self.point_at(self.arc_m))
            b = np.array(self.point_at(self.length_m))
            pieces.append((_bezier(np.linspace(a, b, degree + 1), np.ones(degree + 1)), straight))
        curve, done = pieces[0]
        for piece, length in pieces[1:]:
            curve = join(curve, piece, done / (done + length))
            done += length
        if end is not None:
            ctrl = curve.ctrl.copy()
            ctrl[-1] = end
            curve = dataclasses.replace(curve, ctrl=ctrl)
        return curve

    def _arc_piece(self, a0: float, a1: float, degree: int) -> NurbsCurve:
        """The arc from heading change a0 to a1 (|a1 - a0| <= pi / 2): a rational quadratic
        Bezier (middle weight cos(half angle), at the tangents' intersection) raised to
        `degree` (exact: elevation works on the homogeneous points)."""
        rho = math.copysign(self.radius_m, self.turn_rad)
        p0 = np.array(self.point_at(abs(a0) * self.radius_m))
        p2 = np.array(self.point_at(abs(a1) * self.radius_m))
        half = 0.5 * (a1 - a0)
        th0 = self.start.theta + a0
        p1 = p0 + rho * math.tan(half) * np.array([math.cos(th0), math.sin(th0)])
        pw = np.array([[*p0, 1.0], [*(p1 * math.cos(half)), math.cos(half)], [*p2, 1.0]])
        for _ in range(degree - 2):
            pw = _elevate(pw)
        return _bezier(pw[:, :2] / pw[:, 2:], pw[:, 2])


def _bezier(ctrl: FloatArray, weights: FloatArray) -> NurbsCurve:
    """A single clamped Bezier segment on [0, 1] as a NURBS."""
    p = len(ctrl) - 1
    return NurbsCurve(p, ctrl, weights, np.concatenate([np.zeros(p + 1), np.ones(p + 1)]))


def _elevate(pw: FloatArray) -> FloatArray:
    """Degree elevation of a Bezier by one: Q_i = i/(n+1) P_(i-1) + (1 - i/(n+1)) P_i."""
    n = len(pw) - 1
    a = (np.arange(n + 2) / (n + 1))[:, None]
    prev = np.vstack([pw[:1], pw])  # P_(i-1), with a dummy row at i = 0 (weight a = 0)
    cur = np.vstack([pw, pw[-1:]])  # P_i, with a dummy row at i = n + 1 (weight 1 - a = 0)
    out: FloatArray = a * prev + (1.0 - a) * cur
    return out


def points_along(start: Pose2D, turns: FloatArray, radius: float, s: FloatArray) -> FloatArray:
    """Points (J, K, 2) at arc lengths s (K,) along each way out (J turns): the arc, then
    straight. On the arc, with signed radius rho and heading change a = s / rho (eq. (7)
    integrated at a constant twist, as predict_pose):
    x = x0 + rho (sin(th0 + a) - sin th0),  y = y0 - rho (cos(th0 + a) - cos th0)."""
    sign = np.sign(turns)[:, None]  # (J, 1); 0: straight ahead
    arc = (radius * np.abs(turns))[:, None]
    on_arc = np.minimum(s[None, :], arc)
    a = sign * on_arc / radius
    th = start.theta + a
    rest = s[None, :] - on_arc
    x = start.x + sign * radius * (np.sin(th) - math.sin(start.theta)) + rest * np.cos(th)
    y = start.y - sign * radius * (np.cos(th) - math.cos(start.theta)) + rest * np.sin(th)
    return np.stack([x, y], axis=-1)


@dataclass(frozen=True, eq=False)
class Sweep:
    """Candidate ways out sampled every STEP_M: points, distances, and the start's own."""

    s: FloatArray  # (K,) arc length of each sample
    d: FloatArray  # (J, K) centre to the nearest obstacle surface (moving ones when passed)
    a: FloatArray  # (J, K) centre to the area's nearest edge, negative outside
    d0: float  # the start's d
    a0: float  # the start's a

    def deeper(self, floor_m: float, area_floor_m: float) -> FloatArray:
        """(J, K) the worst depth so far along each way out below min(d0, floor_m) (into an
        obstacle) or min(a0, area_floor_m) (out of the area), whichever is worse."""
        deep = np.maximum(
            np.maximum(min(self.d0, floor_m) - self.d, 0.0),
            np.maximum(min(self.a0, area_floor_m) - self.a, 0.0),
        )
        out: FloatArray = np.maximum.accumulate(deep, axis=1)
        return out


def sweep(
    start: Pose2D,
    turns: FloatArray,
    radius_m: float,
    length_m: float,
    static: StaticField,
    moving: tuple[ObstacleState, ...],
    area: AreaConfig,
    *,
    v_ref: float,
    accel_horizon_s: float,
) -> Sweep:
    """Sample the ways out that turn by `turns` (J,) on arcs of radius_m, up to length_m."""
    s = np.arange(0.0, length_m + STEP_M, STEP_M)  # (K,)
    pts = points_along(start, turns, radius_m, s)  # (J, K, 2)
    t_pass = np.broadcast_to(s[None, :] / v_ref, pts.shape[:2])  # when it gets there
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
    a = to_edge(area, pts[..., 0], pts[..., 1])
    a0 = float(to_edge(area, np.array(start.x), np.array(start.y)))
    return Sweep(s=s, d=d, a=a, d0=d0, a0=a0)


def find_escapes(
    start: Pose2D,
    static: StaticField,
    moving: tuple[ObstacleState, ...],
    area: AreaConfig,
    *,
    r: float,
    rho0: float,
    radius_m: float,
    v_ref: float,
    accel_horizon_s: float,
    max_len_m: float,
) -> list[Escape]:
    """Ways out as in the module docstring, best first; empty if none.

    Distances d are centre to surface (m); `r` is the hull radius, `rho0` the safe distance,
    `radius_m` the arcs' radius; after its arc, a way out runs straight at most `max_len_m`.
    The best is the one to take; the others (at most MAX_ESCAPES in all, end headings at
    least SPREAD_RAD apart) are for when no plan can be made from where the best one ends.
    """
    turns = np.linspace(-math.pi, math.pi, N_TURNS)
    arc = radius_m * np.abs(turns)  # (J,)
    sw = sweep(
        start,
        turns,
        radius_m,
        float(arc.max()) + max_len_m,
        static,
        moving,
        area,
        v_ref=v_ref,
        accel_horizon_s=accel_horizon_s,
    )
    s, d, a, d0, a0 = sw.s, sw.d, sw.a, sw.d0, sw.a0
    # hard: contact no deeper than at the start (no contact at all from a free start), the
    # hull no farther out of the area; soft, for the ranking: how deep into the margin
    ok = (sw.deeper(r, r) <= 1e-9) & (s[None, :] <= arc[:, None] + max_len_m + 1e-9)
    ok = np.logical_and.accumulate(ok, axis=1)
    worst = sw.deeper(r + rho0, r)
    out: list[Escape] = []
    for target in dict.fromkeys((r + rho0 + BEYOND_M, r + 0.25 * rho0 + BEYOND_M)):
        if target <= d0 + BEYOND_M and a0 >= r + BEYOND_M:
            continue  # already that far out: nothing to escape to
        reached = ok & (d >= target) & (a >= r + BEYOND_M)
        # at least one step: a moving obstacle may have drawn off meanwhile, but a way out
        # is a curve (the join needs one, and the vehicle is where it was)
        reached[:, 0] = False
        hit = np.any(reached, axis=1)
        k = np.argmax(reached, axis=1)  # first sample at the target, per turn
        depth = worst[np.arange(len(turns)), k]
        order = sorted(
            np.flatnonzero(hit),
            key=lambda j: (round(depth[j] / DEPTH_STEP_M), s[k[j]], abs(turns[j]), j),
        )
        for j in order:
            if len(out) == MAX_ESCAPES:
                return out
            # a way out that ends on its arc is the same as any larger turn's up to there
            turn = float(np.sign(turns[j])) * min(abs(float(turns[j])), s[k[j]] / radius_m)
            if any(abs(wrap_angle(e.turn_rad - turn)) < SPREAD_RAD for e in out):
                continue
            out.append(
                Escape(
                    start=start,
                    radius_m=radius_m,
                    turn_rad=turn,
                    length_m=float(s[k[j]]),
                    start_clearance_m=d0 - r,
                    end_clearance_m=float(d[j, k[j]]) - r,
                    start_outside_m=max(0.0, r - a0),
                    deeper_m=float(depth[j]),
                )
            )
    return out


def to_edge(area: AreaConfig, x: FloatArray, y: FloatArray) -> FloatArray:
    """Distance from points to the nearest edge of the area, negative outside it."""
    return np.minimum(
        np.minimum(x - area.x_min_m, area.x_max_m - x),
        np.minimum(y - area.y_min_m, area.y_max_m - y),
    )


def prepend_escape(esc: Escape, rest: PlanResult, goal: Pose2D) -> PlanResult:
    """The plan from the start: the way out, then the rest planned from `esc.free`.

    The way out is exact (circular arcs as rational Beziers, a straight run with its control
    points evenly spaced: curvature 1 / radius_m, then 0); the rest leaves the free pose
    along the way out's end heading (eq. (10) boundary constraint), so the join is G1. Each
    piece gets a share of the parameter proportional to its length, so the parameter speed
    barely jumps.
    """
    if not rest.ok:
        return dataclasses.replace(rest, reason=f"{esc.describe()}; from there, {rest.reason}")
    tail = rest.curve()
    line = esc.curve(tail.degree, end=tail.ctrl[0])
    total = esc.length_m + rest.length_m
    curve = join(line, tail, esc.length_m / total)
    a = np.array([esc.start.x, esc.start.y])
    return dataclasses.replace(
        rest,
        reason=esc.describe(),
        control_points=curve.ctrl,
        weights=curve.weights,
        knots=curve.knots,
        grid_path=np.concatenate([a[None, :], rest.grid_path]),
        length_m=total,
        f_l=total / max(math.hypot(goal.x - a[0], goal.y - a[1]), 1e-9),
        max_curvature=max(rest.max_curvature, 1.0 / esc.radius_m if esc.turn_rad else 0.0),
        min_clearance_m=min(esc.start_clearance_m, rest.min_clearance_m),
        escape_m=esc.length_m + rest.escape_m,
        turn_rad=esc.turn_rad,
        margin_entered_m=esc.deeper_m,
    )
