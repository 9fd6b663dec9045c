"""Exact planar polygon geometry: area, centroid, simplicity and vectorised signed distance."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def vertices_array(flat: Sequence[float]) -> FloatArray:
    """Flat (x0, y0, x1, y1, ...) to an (n, 2) array of vertices."""
    return np.asarray(flat, dtype=np.float64).reshape(-1, 2)


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


def polygon_signed_distance(v: FloatArray, px: FloatArray, py: FloatArray) -> FloatArray:
    """Exact Euclidean distance from points to the polygon boundary, negative inside.

    px, py: arrays of one shape; the result has that shape.
    """
    px = np.asarray(px, dtype=np.float64)
    py = np.asarray(py, dtype=np.float64)
    a = v  # edge starts (n, 2)
    b = np.roll(v, -1, axis=0)  # edge ends
    ex, ey = b[:, 0] - a[:, 0], b[:, 1] - a[:, 1]
    qx = px[..., None] - a[:, 0]  # (..., n)
    qy = py[..., None] - a[:, 1]
    # projection parameter of each point onto each edge, clamped to the segment
    u = np.clip((qx * ex + qy * ey) / (ex * ex + ey * ey), 0.0, 1.0)
    d = np.min(np.hypot(qx - u * ex, qy - u * ey), axis=-1)
    # even-odd ray casting towards +x for inside/outside
    ay, by = a[:, 1], b[:, 1]
    straddle = (ay > py[..., None]) != (by > py[..., None])
    with np.errstate(divide="ignore", invalid="ignore"):
        x_cross = a[:, 0] + (py[..., None] - ay) * ex / np.where(ey == 0.0, 1.0, ey)
    hits = np.sum(straddle & (px[..., None] < x_cross), axis=-1)
    inside = (hits % 2) == 1
    return np.where(inside, -d, d)
