"""The planned path as the arc-length reference a controller follows (methods take s).

Controllers query the path several times per step (projection, point, heading, curvature over
a preview window), and command sequences roll them out for every entry. So the path is
tabulated once, on its dense arc-length table (a few centimetres apart), and queries
interpolate linearly (as np.interp, float for float, without its per-call overhead) rather
than evaluate the NURBS: the chord error is below 0.1 mm at the curvatures the planner allows
(docs/notes/planner-arc-length-table.md).
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right

import numpy as np

from services.planner.geometry.planned_path import PlannedPath

_TWO_PI = 2.0 * math.pi


class PathArcReference:
    """Adapts a PlannedPath (parameter u) to the controllers' ArcLengthReference (arc length s)."""

    # the projection searches this window around the previous one, so the controller never
    # jumps to another leg of a path that comes back near itself
    BEHIND_M = 5.0
    AHEAD_M = 15.0

    def __init__(self, path: PlannedPath, v_ref: float) -> None:
        self.path = path
        self._v_ref = v_ref
        self._s = path.s_table
        self._x = path.xy_table[:, 0]
        self._y = path.xy_table[:, 1]
        self._heading = np.unwrap(path.heading_at_u(path.u_table))
        self._k = path.signed_curvature_at_u(path.u_table)
        # the tables as Python lists, for the scalar lookups (bisect and one line of floats)
        self._sl: list[float] = self._s.tolist()
        self._xl: list[float] = self._x.tolist()
        self._yl: list[float] = self._y.tolist()
        self._headingl: list[float] = self._heading.tolist()
        self._kl: list[float] = self._k.tolist()
        k_abs = np.abs(self._k)
        self._k_max = _range_max_table(k_abs)
        # curvature_bound over the whole path (its margin likewise)
        self.curvature_max = float(k_abs.max()) * (1.0 + 1e-9)
        self._length = path.length
        self._stop_s = path.length

    @property
    def length(self) -> float:
        return self._length

    @property
    def stop_s(self) -> float:
        """Where the speed profile brings the vehicle to rest: the path's end, or sooner."""
        return self._stop_s

    def stop_at(self, s: float) -> None:
        """Stop at arc length s at the latest: the path ahead of it is no longer safe to follow
        (a plan to replace it is being made)."""
        self._stop_s = min(self._stop_s, max(s, 0.0))

    @property
    def v_ref(self) -> float:
        return self._v_ref

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        """Arc length of the closest point: nearest table sample, then the exact foot of the
        perpendicular on the neighbouring table segments."""
        # min(a, b) and max(a, b) are written out below (b if b < a else a, b if b > a else
        # a: the same floats): a rollout projects at every entry, ~100k times a mission
        sl, xl, yl = self._sl, self._xl, self._yl
        n = len(sl)
        lo, hi = 0, n
        if s_hint is not None:
            lo = bisect_left(sl, s_hint - self.BEHIND_M)
            hi = bisect_right(sl, s_hint + self.AHEAD_M)
            if lo > n - 1:
                lo = n - 1
            if hi < lo + 1:
                hi = lo + 1
        # (x_i - x)^2 + (y_i - y)^2 in place: the same floats as the plain expression, without
        # its temporaries
        d2 = self._x[lo:hi] - x
        d2 *= d2
        dy = self._y[lo:hi] - y
        dy *= dy
        d2 += dy
        i = lo + int(d2.argmin())
        best_s, best_d2 = sl[i], float(d2[i - lo])
        for j in (i - 1, i):  # the segments before and after the nearest sample
            if j < 0 or j + 1 >= n:
                continue
            ax, ay = xl[j], yl[j]
            bx, by = xl[j + 1] - ax, yl[j + 1] - ay
            seg2 = bx * bx + by * by
            if seg2 <= 0.0:
                continue
            f = ((x - ax) * bx + (y - ay) * by) / seg2
            f = f if f > 0.0 else 0.0  # max(0.0, f)
            f = f if f < 1.0 else 1.0  # min(1.0, f)
            px, py = ax + f * bx, ay + f * by
            dd = (x - px) ** 2 + (y - py) ** 2
            if dd < best_d2:
                best_d2 = dd
                best_s = sl[j] + f * (sl[j + 1] - sl[j])
        return best_s

    # the segment j with s_j <= s < s_{j+1} is bisect_right(s) - 1: -1 before the table,
    # len - 1 at or beyond its end; written out in each query (a call less: these are asked
    # several times for every command entry)
    # and _lerp is written out in them too, x and y sharing the segment's s1 - s0 and s - s0
    # (the same floats as two _lerp calls)
    def point_at_s(self, s: float) -> tuple[float, float]:
        sl, xl, yl = self._sl, self._xl, self._yl
        j = bisect_right(sl, s) - 1
        if j < 0:
            return xl[0], yl[0]
        if j >= len(sl) - 1:
            return xl[-1], yl[-1]
        s0 = sl[j]
        if s == s0:
            return xl[j], yl[j]
        ds, d = sl[j + 1] - s0, s - s0
        x0, y0 = xl[j], yl[j]
        return (xl[j + 1] - x0) / ds * d + x0, (yl[j + 1] - y0) / ds * d + y0

    def heading_at_s(self, s: float) -> float:
        sl = self._sl
        j = bisect_right(sl, s) - 1
        return math.remainder(_lerp(sl, self._headingl, j, s), _TWO_PI)

    def curvature_at_s(self, s: float) -> float:
        sl = self._sl
        return _lerp(sl, self._kl, bisect_right(sl, s) - 1, s)

    def curvature_bound(self, s0: float, s1: float) -> float:
        """An upper bound of |curvature_at_s(s)| for s0 <= s <= s1 (an interpolated value lies
        between its two table samples: the largest |sample| of the segments spanned, one more
        on either side for a query rounded across a node, and a margin over the rounding of
        the interpolation), from a range-maximum table in O(1)."""
        sl, last = self._sl, len(self._sl) - 1
        # max(a, b) and min(a, b) written out (b if b > a else a, b if b < a else a: the same
        # values): the speed profile asks this at every entry of a command sequence
        lo = bisect_right(sl, s0) - 2
        lo = 0 if 0 > lo else lo
        hi = bisect_right(sl, s1) + 1
        hi = last if last < hi else hi
        if hi < lo:
            lo, hi = hi, lo
        level = (hi - lo + 1).bit_length() - 1
        row = self._k_max[level]
        a, b = row[lo], row[hi - (1 << level) + 1]
        return (b if b > a else a) * (1.0 + 1e-9)


def _range_max_table(values: np.ndarray) -> list[list[float]]:
    """Sparse table: row r holds max(values[i : i + 2^r]) at i (a range maximum is then the
    larger of two overlapping rows' entries)."""
    rows = [values]
    while (1 << len(rows)) <= values.size:  # row r exists while 2^r values fit
        half = 1 << (len(rows) - 1)
        rows.append(np.maximum(rows[-1][:-half], rows[-1][half:]))
    return [r.tolist() for r in rows]


def _lerp(xs: list[float], ys: list[float], j: int, x: float) -> float:
    """np.interp(x, xs, ys) on segment j (bisect_right(xs, x) - 1), the same floats without its
    per-call overhead (a controller calls it several times for every command entry): slope
    (y1 - y0) / (x1 - x0) times (x - x0) plus y0, ends held."""
    if j < 0:
        return ys[0]
    if j >= len(xs) - 1:
        return ys[-1]
    if x == xs[j]:
        return ys[j]
    return (ys[j + 1] - ys[j]) / (xs[j + 1] - xs[j]) * (x - xs[j]) + ys[j]
