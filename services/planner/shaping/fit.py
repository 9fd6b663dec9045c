"""NURBS fit of the grid path: the boundary-constrained control polygon of eq. (10).

The control polygon starts as the pruned any-angle waypoints, densified; the first two and
last two control points carry the boundary constraint eq. (10): P0 = start, P1 = start +
a h0 (so the curve leaves along the start heading), P_{n-1} = goal - b hf, P_n = goal.
Where the start (or goal) heading points away from the path, a turning arc of 1.25 R_min
is put in front of the polyline (`turn_arc`), so the polygon does not fold back on itself.
`Layout` maps the free parameters x = (a, b, P2 .. P_{n-3}) to control points as an affine
map P = p_fixed + M x, which the refinement (refine.py) differentiates through.

The weights stay 1 (the NURBS is a B-spline): refining them too barely lowered eq. (9)'s F,
cost far more (the curve is then nonlinear in them) and bent the curve between the
refinement's samples (docs/notes/planner-nurbs-weights-stay-one.md). The evaluation code
handles any positive weights.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from common.config.world import AreaConfig
from common.world import ObstacleState
from common.world.geometry import FloatArray
from services.planner.geometry.clearance import StaticField
from services.planner.geometry.nurbs_curve import NurbsCurve, averaged_knots
from services.planner.result import Pose2D
from services.planner.search.costmap import CostMap


@dataclass(frozen=True, eq=False)
class FitProblem:
    """What the curve must satisfy: boundary poses, obstacles, vehicle limits, clearances."""

    start: Pose2D
    goal: Pose2D
    fix_goal_heading: bool
    area: AreaConfig
    static: StaticField
    moving: tuple[ObstacleState, ...]
    vehicle_radius_m: float
    r_min_m: float
    v_ref_mps: float  # the speed over ground: passing times t = s / v_ref_mps (eq. (13))
    d_req_m: float  # required centre-to-surface clearance r + rho0 (eq. (12)-(13) with r_k)
    escape_len_m: float  # from a start inside the margin only d >= r is required this far
    start_inside: bool
    accel_horizon_s: float
    grid: CostMap  # its bilinear static clearance drives the refinement (exact check later)

    def required(self, s: FloatArray) -> FloatArray:
        """Required centre-to-surface clearance at arc length s."""
        if not self.start_inside:
            return np.full(len(s), self.d_req_m)
        return np.where(s < self.escape_len_m, self.vehicle_radius_m, self.d_req_m)


def densify(points: FloatArray, spacing: float) -> FloatArray:
    """The polyline through `points` with extra vertices so no piece is longer than spacing."""
    out = [points[:1]]
    for a, b in zip(points[:-1], points[1:], strict=True):
        n = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing))
        t = np.linspace(0.0, 1.0, n + 1)[1:, None]
        out.append(a[None, :] * (1.0 - t) + b[None, :] * t)
    return np.concatenate(out)


class Layout:
    """Affine map x -> control points, P.ravel() = p_fixed + M x (boundary constraint eq. (10)).

    x = (a, [b,] P2.x, P2.y, ...): a, b > 0 are the tangent lengths at start and goal; with
    a free goal heading P_{n-1} is an ordinary free point and b is absent.
    """

    def __init__(self, prob: FitProblem, n_ctrl: int) -> None:
        self.n = n_ctrl
        s = np.array([prob.start.x, prob.start.y])
        g = np.array([prob.goal.x, prob.goal.y])
        self.h0 = np.array([math.cos(prob.start.theta), math.sin(prob.start.theta)])
        self.hf = np.array([math.cos(prob.goal.theta), math.sin(prob.goal.theta)])
        self.fix_goal = prob.fix_goal_heading
        self.n_head = 2 if self.fix_goal else 1
        self.free_hi = n_ctrl - 2 if self.fix_goal else n_ctrl - 1  # free: P2 .. P_{free_hi-1}
        n_free = 2 * (self.free_hi - 2)
        fixed = np.zeros((n_ctrl, 2))
        fixed[0] = fixed[1] = s
        fixed[-1] = g
        m = np.zeros((n_ctrl, 2, self.n_head + n_free))
        m[1, :, 0] = self.h0
        if self.fix_goal:
            fixed[-2] = g
            m[-2, :, 1] = -self.hf
        i = np.arange(self.free_hi - 2)
        m[2 + i, 0, self.n_head + 2 * i] = 1.0
        m[2 + i, 1, self.n_head + 2 * i + 1] = 1.0
        self.p_fixed = fixed.ravel()
        self.m = m.reshape(2 * n_ctrl, -1)

    @property
    def dim(self) -> int:
        return int(self.m.shape[1])

    def to_x(self, ctrl: FloatArray) -> FloatArray:
        head = [float(np.dot(ctrl[1] - ctrl[0], self.h0))]
        if self.fix_goal:
            head.append(float(np.dot(ctrl[-1] - ctrl[-2], self.hf)))
        return np.concatenate([head, ctrl[2 : self.free_hi].ravel()])

    def ctrl(self, x: FloatArray) -> FloatArray:
        return (self.p_fixed + self.m @ x).reshape(self.n, 2)

    def bounds(
        self, area: AreaConfig, margin: float, tangent_max: float
    ) -> tuple[FloatArray, FloatArray]:
        """Box bounds: tangent lengths in [0.05, tangent_max], free points inside the area.

        The curve lies in the convex hull of its control points (positive weights), so this
        keeps it inside the area X of eq. (9)-(10).
        """
        n_pts = self.free_hi - 2
        lo = [0.05] * self.n_head + [area.x_min_m + margin, area.y_min_m + margin] * n_pts
        hi = [tangent_max] * self.n_head + [area.x_max_m - margin, area.y_max_m - margin] * n_pts
        return np.array(lo), np.array(hi)


def turn_arc(pts: FloatArray, theta: float, radius: float) -> tuple[FloatArray, int]:
    """A turn of `radius` from pose (pts[0], theta) until it heads for the path ahead.

    The grid path ignores headings; when the vehicle points away from its first leg (more
    than 45 degrees) the fitted polygon would fold back on itself, so a turning arc (at
    most half a circle) replaces the start of the polyline. The target is the first point
    at least 2 radius away (points before it lie where the turn goes). Returns the arc
    points (k, 2), empty when no turn is needed, and the index of the first point to keep.
    """
    p = pts[0]
    far = np.flatnonzero(np.hypot(*(pts[1:] - p).T) >= 2.0 * radius)
    i_keep = int(far[0]) + 1 if len(far) else len(pts) - 1
    toward = pts[i_keep]
    to = toward - p
    delta = math.remainder(math.atan2(to[1], to[0]) - theta, math.tau)
    if abs(delta) <= math.pi / 4:
        return np.zeros((0, 2)), 1
    sgn = 1.0 if delta > 0.0 else -1.0
    normal = sgn * np.array([-math.sin(theta), math.cos(theta)])
    centre = p + radius * normal
    out = []
    for i in range(1, 9):  # heading steps of 22.5 degrees, up to 180
        phi = theta + sgn * i * math.pi / 8.0
        a = centre - radius * sgn * np.array([-math.sin(phi), math.cos(phi)])
        out.append(a)
        d = toward - a
        if abs(math.remainder(math.atan2(d[1], d[0]) - phi, math.tau)) <= math.pi / 8.0:
            break
    return np.array(out), i_keep


def initial_curve(
    prob: FitProblem, waypoints: FloatArray, spacing: float, degree: int
) -> NurbsCurve:
    """Control polygon from the densified waypoints plus the boundary tangents of eq. (10)."""
    radius = 1.25 * prob.r_min_m
    lead, i0 = turn_arc(waypoints, prob.start.theta, radius)
    tail, j0 = np.zeros((0, 2)), 1
    if prob.fix_goal_heading:  # the same turn, planned backwards from the goal
        tail, j0 = turn_arc(waypoints[::-1], prob.goal.theta + math.pi, radius)
        tail = tail[::-1]
    mid = waypoints[i0 : len(waypoints) - j0]  # empty when the two turns overlap
    waypoints = np.concatenate([waypoints[:1], lead, mid, tail, waypoints[-1:]])
    total = float(np.sum(np.hypot(*np.diff(waypoints, axis=0).T)))
    spacing = min(spacing, max(total / (degree + 2), 1e-3))
    dense = densify(waypoints, spacing)
    first = float(np.hypot(*(dense[1] - dense[0]))) if len(dense) > 1 else total
    a = min(prob.r_min_m, 0.5 * first, 0.5 * spacing)
    lay = Layout(prob, len(dense) + 2)
    last_dir = dense[-1] - dense[-2]
    last_dir = last_dir / max(float(np.hypot(*last_dir)), 1e-12)
    hf = lay.hf if prob.fix_goal_heading else last_dir
    start_xy, goal_xy = dense[0], dense[-1]
    b = min(prob.r_min_m, 0.5 * float(np.hypot(*(dense[-1] - dense[-2]))), 0.5 * spacing)
    ctrl = np.concatenate(
        [dense[:1], [start_xy + a * lay.h0], dense[1:-1], [goal_xy - b * hf], dense[-1:]]
    )
    return NurbsCurve(degree, ctrl, np.ones(len(ctrl)), averaged_knots(ctrl, degree))


def resample(curve: NurbsCurve, spacing: float) -> FloatArray:
    """Points along a curve about `spacing` apart in arc length (ends included)."""
    u = np.linspace(curve.u_min, curve.u_max, 400)
    pts = curve.evaluate(u, n_ders=0)[0]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    n = max(2, math.ceil(s[-1] / spacing) + 1)
    at = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(at, s, pts[:, 0]), np.interp(at, s, pts[:, 1])], axis=1)
