"""The planned path as the arc-length reference a controller follows (methods take s).

Controllers query the path several times per step (projection, point, heading, curvature over
a preview window). Evaluating the NURBS each time cost about a millisecond per step, so the
path is tabulated once, on its dense arc-length table (a few centimetres apart), and queries
interpolate: the chord error is below 0.1 mm at the curvatures the planner allows.
"""

from __future__ import annotations

import math

import numpy as np

from services.planner.planned_path import PlannedPath


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

    @property
    def length(self) -> float:
        return self.path.length

    @property
    def v_ref(self) -> float:
        return self._v_ref

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        """Arc length of the closest point: nearest table sample, then the exact foot of the
        perpendicular on the neighbouring table segments."""
        lo, hi = 0, len(self._s)
        if s_hint is not None:
            lo = int(np.searchsorted(self._s, s_hint - self.BEHIND_M, side="left"))
            hi = int(np.searchsorted(self._s, s_hint + self.AHEAD_M, side="right"))
            lo, hi = min(lo, len(self._s) - 1), max(hi, lo + 1)
        d2 = (self._x[lo:hi] - x) ** 2 + (self._y[lo:hi] - y) ** 2
        i = lo + int(np.argmin(d2))
        best_s, best_d2 = float(self._s[i]), float(d2[i - lo])
        for j in (i - 1, i):  # the segments before and after the nearest sample
            if j < 0 or j + 1 >= len(self._s):
                continue
            ax, ay = self._x[j], self._y[j]
            bx, by = self._x[j + 1] - ax, self._y[j + 1] - ay
            seg2 = bx * bx + by * by
            if seg2 <= 0.0:
                continue
            f = min(1.0, max(0.0, ((x - ax) * bx + (y - ay) * by) / seg2))
            px, py = ax + f * bx, ay + f * by
            dd = (x - px) ** 2 + (y - py) ** 2
            if dd < best_d2:
                best_d2 = dd
                best_s = float(self._s[j] + f * (self._s[j + 1] - self._s[j]))
        return best_s

    def point_at_s(self, s: float) -> tuple[float, float]:
        return float(np.interp(s, self._s, self._x)), float(np.interp(s, self._s, self._y))

    def heading_at_s(self, s: float) -> float:
        return math.remainder(float(np.interp(s, self._s, self._heading)), 2.0 * math.pi)

    def curvature_at_s(self, s: float) -> float:
        return float(np.interp(s, self._s, self._k))
