"""The planner's clearance fields: exact vectorised distances (and gradients) to obstacles.

The static field stacks the chart's circles and polygons into arrays once per plan, so one
call evaluates many points against every obstacle without Python loops; polygons use the
world's one signed distance (common.world.geometry.PolygonEdges).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache

import numpy as np

from common.config.world import CircleObstacleConfig, PolygonObstacleConfig
from common.world import ObstacleState
from common.world.geometry import FloatArray, PolygonEdges, vertices_array

_FAR_M = 1.0e6  # distance reported where there is no obstacle at all


@dataclass(frozen=True, eq=False)
class StaticField:
    """Exact signed distance (m) from points to the nearest static obstacle surface, vectorised.

    Negative inside an obstacle.
    """

    circ: FloatArray  # (nc, 3): x, y, radius
    edges: PolygonEdges  # every polygon's edges, polygons contiguous
    bbox: FloatArray = field(repr=False)  # (nobs, 4): x_min, y_min, x_max, y_max per obstacle
    # the cost map's static clearance grids on this field, by grid (costmap.py): one ask
    # builds a cost map for every plan it makes (remade, recovered), all on one chart
    grids: dict[tuple[object, ...], FloatArray] = field(
        default_factory=dict, compare=False, repr=False
    )

    @staticmethod
    @lru_cache(maxsize=8)
    def build(
        circles: tuple[CircleObstacleConfig, ...], polygons: tuple[PolygonObstacleConfig, ...]
    ) -> StaticField:
        """The field of a chart's circles and polygons: one (read-only) per chart, for the
        chart stays the same from plan to plan."""
        circ = np.array([(c.x_m, c.y_m, c.radius_m) for c in circles], dtype=np.float64)
        circ = circ.reshape(-1, 3)
        verts = [vertices_array(p.vertices_m) for p in polygons]
        boxes = [(x - r, y - r, x + r, y + r) for x, y, r in circ.tolist()]
        boxes += [(*v.min(axis=0), *v.max(axis=0)) for v in verts]
        bbox = np.array(boxes, dtype=np.float64).reshape(-1, 4)
        edges = PolygonEdges.of(verts)
        for a in (circ, bbox, edges.a, edges.b, edges.starts, edges.edge_poly):
            a.setflags(write=False)
        return StaticField(circ, edges, bbox)

    @property
    def empty(self) -> bool:
        return len(self.circ) == 0 and len(self.edges.a) == 0

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
        if len(self.edges.a):
            dp, gp = self.edges.signed_distance(pts)
            closer = dp < best
            best = np.where(closer, dp, best)
            grad = np.where(closer[:, None], gp, grad)
        return best, grad

    def polygon(self, p: int) -> PolygonEdges:
        """The edges of polygon p alone."""
        sel = self.edges.edge_poly == p
        return PolygonEdges(
            self.edges.a[sel],
            self.edges.b[sel],
            np.zeros(1, np.intp),
            np.zeros(int(sel.sum()), np.intp),
        )


def moving_distance(
    moving: tuple[ObstacleState, ...], pts: FloatArray, t_s: FloatArray, accel_horizon_s: float
) -> tuple[FloatArray, FloatArray]:
    """Eq. (12) distance ||x(t) - alpha_k(t)|| - r_k to the nearest moving obstacle, + gradient.

    Point j is compared with every obstacle at its own time t_s[j] (when the vehicle is there).
    """
    pts = np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    m = len(pts)
    if not moving:
        return np.full(m, _FAR_M), np.zeros((m, 2))
    centres = np.stack([o.centre_at(t_s, accel_horizon_s) for o in moving])  # (k, m, 2)
    radii = np.array([o.radius for o in moving])
    diff = pts[None, :, :] - centres
    r = np.sqrt(np.einsum("kmd,kmd->km", diff, diff))
    d = r - radii[:, None]
    k = np.argmin(d, axis=0)
    rows = np.arange(m)
    grad = diff[k, rows] / np.maximum(r[k, rows], 1e-12)[:, None]
    return d[k, rows], grad


def current_pushes_clear(
    x: float,
    y: float,
    static: StaticField,
    moving: tuple[ObstacleState, ...],
    current: tuple[float, float],
    keep_m: float,
) -> bool:
    """Whether the current carries a vehicle at (x, y) away from the obstacle nearest it, one
    within `keep_m` of its centre (moving obstacles as they are now): that obstacle lies
    upstream, and station kept against the current would hold the hull at it."""
    pts = np.array([[x, y]])
    d, grad = static.distance(pts)
    dm, gm = moving_distance(moving, pts, np.zeros(1), 0.0)
    near, away = (d[0], grad[0]) if d[0] <= dm[0] else (dm[0], gm[0])
    return bool(near < keep_m and float(away @ np.asarray(current)) > 0.0)
