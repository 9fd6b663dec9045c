"""Planner world geometry: poses, area, obstacles, and exact vectorised clearance fields."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

_FAR_M = 1.0e6  # distance reported where there is no obstacle at all


@dataclass(frozen=True, kw_only=True)
class Pose2D:
    """A planar pose: position (m) and heading theta (rad, from +x, counter-clockwise)."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True, kw_only=True)
class Area:
    """The rectangular operating area X of eq. (10) (paper section 4: 100 m x 40 m)."""

    x_min: float = 0.0
    x_max: float = 100.0
    y_min: float = 0.0
    y_max: float = 40.0

    def __post_init__(self) -> None:
        if not (self.x_max > self.x_min and self.y_max > self.y_min):
            raise ValueError(f"area: {self!r} is empty, expected x_max > x_min and y_max > y_min")

    def contains(self, x: float, y: float, margin: float = 0.0) -> bool:
        return (
            self.x_min + margin <= x <= self.x_max - margin
            and self.y_min + margin <= y <= self.y_max - margin
        )


@dataclass(frozen=True, kw_only=True)
class Circle:
    """A static circular obstacle (centre and radius r_k, m)."""

    x: float
    y: float
    radius: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.radius) and self.radius >= 0.0):
            raise ValueError(f"circle.radius: {self.radius!r} is invalid, expected >= 0")


@dataclass(frozen=True, kw_only=True)
class Polygon:
    """A static polygonal obstacle: a simple polygon given by its vertices (m), either order."""

    vertices: tuple[tuple[float, float], ...]

    def __post_init__(self) -> None:
        if len(self.vertices) < 3:
            raise ValueError(f"polygon.vertices: {len(self.vertices)} given, expected >= 3")


@dataclass(frozen=True, kw_only=True)
class MovingCircle:
    """A tracked moving obstacle: state at plan time t = 0 (position, velocity, acceleration)."""

    id: int = 0
    x: float
    y: float
    vx: float = 0.0
    vy: float = 0.0
    ax: float = 0.0
    ay: float = 0.0
    radius: float

    def shifted(self, dt_s: float) -> MovingCircle:
        """The same obstacle with its state extrapolated by dt_s (to align track and plan time)."""
        p = self.positions(np.array([dt_s]), accel_horizon_s=math.inf)[0]
        return MovingCircle(
            id=self.id,
            x=float(p[0]),
            y=float(p[1]),
            vx=self.vx + self.ax * dt_s,
            vy=self.vy + self.ay * dt_s,
            ax=self.ax,
            ay=self.ay,
            radius=self.radius,
        )

    def positions(self, t: FloatArray, accel_horizon_s: float) -> FloatArray:
        """alpha_k(t) = p + v t + a t^2 / 2 (eq. (12)), acceleration held only up to the horizon.

        A tracked acceleration extrapolated for a minute would fling the obstacle across the
        area, so past `accel_horizon_s` the obstacle keeps the velocity it has reached.
        """
        t = np.asarray(t, dtype=np.float64)
        ta = np.minimum(t, accel_horizon_s)
        quad = 0.5 * ta * ta + ta * (t - ta)  # integral of min(t, T_a): acceleration term
        x = self.x + self.vx * t + self.ax * quad
        y = self.y + self.vy * t + self.ay * quad
        return np.stack([x, y], axis=-1)


@dataclass(frozen=True, kw_only=True)
class Obstacles:
    """Everything the planner avoids: static circles and polygons, tracked moving circles."""

    circles: tuple[Circle, ...] = ()
    polygons: tuple[Polygon, ...] = ()
    moving: tuple[MovingCircle, ...] = ()


@dataclass(frozen=True, eq=False)
class StaticField:
    """Exact signed distance (m) from points to the nearest static obstacle surface, vectorised.

    Negative inside an obstacle. All primitives are stacked into arrays once, so one call
    evaluates every point against every circle and polygon edge without Python loops.
    """

    circ: FloatArray  # (nc, 3): x, y, radius
    edge_a: FloatArray  # (ne, 2) polygon edge start points, polygons contiguous
    edge_b: FloatArray  # (ne, 2) polygon edge end points
    poly_starts: NDArray[np.intp]  # (npoly,) first edge of each polygon
    edge_poly: NDArray[np.intp]  # (ne,) polygon index of each edge
    bbox: FloatArray = field(repr=False)  # (nobs, 4): x_min, y_min, x_max, y_max per obstacle

    @staticmethod
    def build(circles: tuple[Circle, ...], polygons: tuple[Polygon, ...]) -> StaticField:
        circ = np.array([(c.x, c.y, c.radius) for c in circles], dtype=np.float64).reshape(-1, 3)
        verts = [np.asarray(p.vertices, dtype=np.float64) for p in polygons]
        a = np.concatenate(verts) if verts else np.zeros((0, 2))
        b = np.concatenate([np.roll(v, -1, axis=0) for v in verts]) if verts else np.zeros((0, 2))
        starts = np.cumsum([0] + [len(v) for v in verts[:-1]]).astype(np.intp)
        edge_poly = np.repeat(np.arange(len(verts)), [len(v) for v in verts]).astype(np.intp)
        boxes = [(c.x - c.radius, c.y - c.radius, c.x + c.radius, c.y + c.radius) for c in circles]
        boxes += [(*v.min(axis=0), *v.max(axis=0)) for v in verts]
        bbox = np.array(boxes, dtype=np.float64).reshape(-1, 4)
        starts = starts if verts else np.zeros(0, np.intp)
        return StaticField(circ, a, b, starts, edge_poly, bbox)

    @property
    def empty(self) -> bool:
        return len(self.circ) == 0 and len(self.edge_a) == 0

    def distance(self, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Signed distance (m,) to the nearest surface and its gradient (m, 2) w.r.t. the point."""
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
        m = len(pts)
        best = np.full(m, _FAR_M)
        grad = np.zeros((m, 2))
        if len(self.circ):
            diff = pts[:, None, :] - self.circ[None, :, :2]  # (m, nc, 2)
            r = np.sqrt(np.einsum("mkd,mkd->mk", diff, diff))
            d = r - self.circ[None, :, 2]
            k = np.argmin(d, axis=1)
            rows = np.arange(m)
            best = d[rows, k]
            rk = np.maximum(r[rows, k], 1e-12)
            grad = diff[rows, k] / rk[:, None]
        if len(self.edge_a):
            dp, gp = self._polygon_distance(pts)
            closer = dp < best
            best = np.where(closer, dp, best)
            grad = np.where(closer[:, None], gp, grad)
        return best, grad

    def _polygon_distance(self, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
        a, b = self.edge_a, self.edge_b
        ab = b - a  # (ne, 2)
        ap = pts[:, None, :] - a[None, :, :]  # (m, ne, 2)
        len2 = np.maximum(np.einsum("ed,ed->e", ab, ab), 1e-18)
        t = np.clip(np.einsum("med,ed->me", ap, ab) / len2, 0.0, 1.0)
        diff = ap - t[:, :, None] * ab[None, :, :]  # point minus closest point on the edge
        d2 = np.einsum("med,med->me", diff, diff)
        # even-odd crossing test of a ray towards +x, per edge, summed per polygon
        py = pts[:, 1:2]
        ay, by = a[None, :, 1], b[None, :, 1]
        straddle = (ay > py) != (by > py)
        dy = np.where(by == ay, 1.0, by - ay)
        x_cross = a[None, :, 0] + (py - ay) * ab[None, :, 0] / dy
        crosses = (straddle & (pts[:, 0:1] < x_cross)).astype(np.int64)
        rows = np.arange(len(pts))
        inside = np.add.reduceat(crosses, self.poly_starts, axis=1) % 2 == 1  # (m, npoly)
        d2_poly = np.minimum.reduceat(d2, self.poly_starts, axis=1)
        dist = np.sqrt(d2_poly)
        signed = np.where(inside, -dist, dist)
        kp = np.argmin(signed, axis=1)
        best = signed[rows, kp]
        # the nearest edge of the chosen polygon gives the gradient direction
        d2_masked = np.where(self.edge_poly[None, :] == kp[:, None], d2, np.inf)
        ke = np.argmin(d2_masked, axis=1)
        g = diff[rows, ke]
        g = g / np.maximum(np.sqrt(d2[rows, ke]), 1e-12)[:, None]
        g = np.where(inside[rows, kp][:, None], -g, g)
        return best, g


def moving_distance(
    moving: tuple[MovingCircle, ...], pts: FloatArray, t_s: FloatArray, accel_horizon_s: float
) -> tuple[FloatArray, FloatArray]:
    """Eq. (12) distance ||x(t) - alpha_k(t)|| - r_k to the nearest moving obstacle, + gradient.

    Point j is compared with every obstacle at its own time t_s[j] (when the vehicle is there).
    """
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    m = len(pts)
    if not moving:
        return np.full(m, _FAR_M), np.zeros((m, 2))
    centres = np.stack([o.positions(t_s, accel_horizon_s) for o in moving])  # (k, m, 2)
    radii = np.array([o.radius for o in moving])
    diff = pts[None, :, :] - centres
    r = np.sqrt(np.einsum("kmd,kmd->km", diff, diff))
    d = r - radii[:, None]
    k = np.argmin(d, axis=0)
    rows = np.arange(m)
    grad = diff[k, rows] / np.maximum(r[k, rows], 1e-12)[:, None]
    return d[k, rows], grad
