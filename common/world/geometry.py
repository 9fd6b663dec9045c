"""Exact planar geometry: polygon area, centroid, simplicity, vectorised signed distance;
nearest-point distances; bounding boxes."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]
BoolArray = NDArray[np.bool_]


def vertices_array(flat: Sequence[float]) -> FloatArray:
    """Flat (x0, y0, x1, y1, ...) to an (n, 2) array of vertices."""
    return np.asarray(flat, dtype=np.float64).reshape(-1, 2)


@dataclass(frozen=True, slots=True)
class Box:
    """An axis-aligned bounding box."""

    x_min: float
    y_min: float
    x_max: float
    y_max: float

    @staticmethod
    def of(x: FloatArray, y: FloatArray) -> Box:
        """The box of the points (x[i], y[i]) (at least one)."""
        return Box(float(x.min()), float(y.min()), float(x.max()), float(y.max()))

    def distance(self, other: Box) -> float:
        """The least distance between a point of this box and one of the other (0 if they
        overlap): a lower bound on the distance between anything inside each."""
        dx = max(0.0, other.x_min - self.x_max, self.x_min - other.x_max)
        dy = max(0.0, other.y_min - self.y_max, self.y_min - other.y_max)
        return float(np.hypot(dx, dy))


def polygon_area(v: FloatArray) -> float:
    """Signed area (shoelace formula); positive for counter-clockwise vertices."""
    x, y = v[:, 0], v[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(np.roll(x, -1), y))


def polygon_centroid(v: FloatArray) -> tuple[float, float]:
    """Area centroid of a simple polygon."""
    x, y = v[:, 0], v[:, 1]
    xn, yn = np.roll(x, -1), np.roll(y, -1)
    cross = x * yn - xn * y
    a6 = 3.0 * float(np.sum(cross))  # 6 * signed area
    return float(np.sum((x + xn) * cross)) / a6, float(np.sum((y + yn) * cross)) / a6


def _segments_cross(p: FloatArray, q: FloatArray, r: FloatArray, s: FloatArray) -> bool:
    """Do the closed segments pq and rs intersect (touching counts)?"""

    def orient(a: FloatArray, b: FloatArray, c: FloatArray) -> float:
        return float((b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]))

    d1, d2 = orient(r, s, p), orient(r, s, q)
    d3, d4 = orient(p, q, r), orient(p, q, s)
    if d1 * d2 < 0.0 and d3 * d4 < 0.0:
        return True
    eps = 1e-12

    def on(a: FloatArray, b: FloatArray, c: FloatArray, d: float) -> bool:
        return (
            abs(d) <= eps
            and min(a[0], b[0]) - eps <= c[0] <= max(a[0], b[0]) + eps
            and (min(a[1], b[1]) - eps <= c[1] <= max(a[1], b[1]) + eps)
        )

    return on(r, s, p, d1) or on(r, s, q, d2) or on(p, q, r, d3) or on(p, q, s, d4)


def polygon_is_simple(v: FloatArray) -> bool:
    """True when no two non-adjacent edges intersect (O(n^2); polygons here are small)."""
    n = len(v)
    for i in range(n):
        for j in range(i + 1, n):
            if j == i + 1 or (i == 0 and j == n - 1):
                continue  # adjacent edges share a vertex by construction
            if _segments_cross(v[i], v[(i + 1) % n], v[j], v[(j + 1) % n]):
                return False
    return True


@dataclass(frozen=True, eq=False)
class PolygonEdges:
    """The edges of one or more polygons stacked into arrays, for vectorised signed distance."""

    a: FloatArray  # (ne, 2) edge start points, polygons contiguous
    b: FloatArray  # (ne, 2) edge end points
    starts: NDArray[np.intp]  # (npoly,) first edge of each polygon
    edge_poly: NDArray[np.intp]  # (ne,) polygon index of each edge

    @staticmethod
    def of(polygons: Sequence[FloatArray]) -> PolygonEdges:
        """Edges of polygons given as (n, 2) vertex arrays, either winding."""
        a = np.concatenate(polygons) if polygons else np.zeros((0, 2))
        b = np.concatenate([np.roll(v, -1, axis=0) for v in polygons]) if polygons else a
        sizes = [len(v) for v in polygons]
        starts = np.cumsum([0] + sizes[:-1]).astype(np.intp) if polygons else np.zeros(0, np.intp)
        edge_poly = np.repeat(np.arange(len(polygons)), sizes).astype(np.intp)
        return PolygonEdges(a, b, starts, edge_poly)

    def signed_distance(self, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Distance (m,) from points (m, 2) to the nearest polygon's boundary, negative inside,
        and its gradient (m, 2) w.r.t. the point (the unit normal of the nearest edge)."""
        signed, inside, d2, diff = self._per_polygon(pts)
        rows = np.arange(len(pts))
        kp = np.argmin(signed, axis=1)
        best = signed[rows, kp]
        # the nearest edge of the chosen polygon gives the gradient direction
        d2_masked = np.where(self.edge_poly[None, :] == kp[:, None], d2, np.inf)
        ke = np.argmin(d2_masked, axis=1)
        g = diff[rows, ke]
        g = g / np.maximum(np.sqrt(d2[rows, ke]), 1e-12)[:, None]
        g = np.where(inside[rows, kp][:, None], -g, g)
        return best, g

    def signed_distances(self, pts: FloatArray) -> FloatArray:
        """Each polygon's signed distance (m, npoly) from points (m, 2): signed_distance's
        floats before the least is taken, without the gradient's cost."""
        return self._per_polygon(pts)[0]

    def _per_polygon(self, pts: FloatArray) -> tuple[FloatArray, BoolArray, FloatArray, FloatArray]:
        """Signed distance (m, npoly) and inside (m, npoly) per polygon; each edge's squared
        distance (m, ne) and point minus closest point (m, ne, 2)."""
        a, b = self.a, self.b
        ab = b - a  # (ne, 2)
        ap = pts[:, None, :] - a[None, :, :]  # (m, ne, 2)
        len2 = np.maximum(np.einsum("ed,ed->e", ab, ab), 1e-18)
        # projection parameter of each point onto each edge, clamped to the segment
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
        inside = np.add.reduceat(crosses, self.starts, axis=1) % 2 == 1  # (m, npoly)
        d2_poly = np.minimum.reduceat(d2, self.starts, axis=1)
        dist = np.sqrt(d2_poly)
        return np.where(inside, -dist, dist), inside, d2, diff


def polygon_signed_distance(v: FloatArray, px: ArrayLike, py: ArrayLike) -> FloatArray:
    """Exact Euclidean distance from points to the polygon boundary, negative inside.

    px, py: arrays of one shape; the result has that shape.
    """
    bx, by = np.broadcast_arrays(np.asarray(px, np.float64), np.asarray(py, np.float64))
    pts = np.stack([bx.ravel(), by.ravel()], axis=1)
    return PolygonEdges.of([v]).signed_distances(pts)[:, 0].reshape(bx.shape)


def nearest_distances(
    points: FloatArray, to: FloatArray, *, block: int = 256, leaf: int = 64
) -> FloatArray:
    """For each of `points` (N, 2), the distance (m) to the nearest of `to` (M, 2, M >= 1):
    (N,). Exact: the very floats of comparing every pair (`_nearest_every_pair`), pruned.

    `to` is cut into runs of `leaf` consecutive samples (a path's samples lie along it, so a
    run is compact), each with its bounding box. A box's distance to a point, computed with
    the pair's own operations on the box's edges, is no more than any of its samples' squared
    distance as computed (IEEE subtraction, squaring and addition are monotone), so only the
    runs whose box beats the best found so far are compared in full, and the minimum over
    those is the minimum over all. `block` rows at a time bound the memory. scipy.spatial's
    KD-tree is not used: its import costs a launch or a run more than its queries save.
    """
    if len(to) <= 2 * leaf or not (np.isfinite(points).all() and np.isfinite(to).all()):
        return _nearest_every_pair(points, to, block=block)  # nothing to prune, or NaN/inf
    runs = -(-len(to) // leaf)
    # the last run padded with its last sample: a repeated sample changes no minimum
    padded = np.concatenate([to, np.repeat(to[-1:], runs * leaf - len(to), axis=0)])
    rx, ry = padded[:, 0].reshape(runs, leaf), padded[:, 1].reshape(runs, leaf)
    x_lo, x_hi, y_lo, y_hi = rx.min(axis=1), rx.max(axis=1), ry.min(axis=1), ry.max(axis=1)
    out = np.empty(len(points))
    for i in range(0, len(points), block):
        px, py = points[i : i + block, 0, None], points[i : i + block, 1, None]
        # squared distance to each run's box (b, runs): 0 along an axis the point is within
        dx = np.maximum(np.maximum(x_lo - px, px - x_hi), 0.0)
        dy = np.maximum(np.maximum(y_lo - py, py - y_hi), 0.0)
        dx *= dx
        dy *= dy
        dx += dy
        # the best so far: every sample of the run whose box is nearest
        first = np.argmin(dx, axis=1)
        best = _squared_min(px, py, rx[first], ry[first])
        # then every other run whose box could hold a nearer sample, point by point
        dx[np.arange(len(first)), first] = np.inf
        pi, ri = np.nonzero(dx < best[:, None])
        if len(pi):
            d2 = _squared_min(px[pi], py[pi], rx[ri], ry[ri])
            np.minimum.at(best, pi, d2)
        out[i : i + block] = best
    return np.sqrt(out)


def _nearest_every_pair(points: FloatArray, to: FloatArray, *, block: int) -> FloatArray:
    """nearest_distances by comparing every pair, `block` rows of points at a time."""
    out = np.empty(len(points))
    for i in range(0, len(points), block):
        out[i : i + block] = _squared_min(
            points[i : i + block, 0, None], points[i : i + block, 1, None], to[:, 0], to[:, 1]
        )
    return np.sqrt(out)


def _squared_min(px: FloatArray, py: FloatArray, qx: FloatArray, qy: FloatArray) -> FloatArray:
    """min over each row of (px - qx)^2 + (py - qy)^2: px, py (b, 1); qx, qy (m,) or (b, m)."""
    dx = px - qx
    dy = py - qy
    dx *= dx
    dy *= dy
    dx += dy
    return dx.min(axis=1)
