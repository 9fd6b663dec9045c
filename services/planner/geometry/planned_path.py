"""The planned path: a NURBS curve with its arc-length table s(u), u(s); methods take u.

Every method named `*_at_u` takes the curve parameter u; `s_at_u` / `u_at_s` convert to and
from arc length s, and `closest_u` projects a point onto the curve.
"""

from __future__ import annotations

import numpy as np

from common.messages import PathMsg
from common.world.geometry import FloatArray
from services.planner.geometry.nurbs_curve import NurbsCurve, curvature

# 3-point Gauss-Legendre on [0, 1]: exact for polynomials of degree 5 between table points
_GL_X = 0.5 + 0.5 * np.array([-np.sqrt(0.6), 0.0, np.sqrt(0.6)])
_GL_W = np.array([5.0, 8.0, 5.0]) / 18.0


def curve_of(p: PathMsg) -> NurbsCurve:
    """The NURBS curve a path message carries (status OK), exactly as it was planned."""
    cp = np.asarray(p.control_points, dtype=np.float64).reshape(-1, 2)
    return NurbsCurve(p.degree, cp, np.asarray(p.weights), np.asarray(p.knots))


class PlannedPath:
    """A curve with a dense table of parameters, points and arc length, built once per path.

    `closest_u` finds the closest parameter to a point: nearest table sample (optionally inside
    a parameter window, so a controller does not jump to another leg of the path), then
    Newton steps on f(u) = (C(u) - q) . C'(u) = 0.
    """

    def __init__(
        self, curve: NurbsCurve, n_table: int = 2000, samples: FloatArray | None = None
    ) -> None:
        """`samples`: the curve's points and first two derivatives (3, m, 2) at m parameters
        uniform over its domain, evaluated already (the plan's dense check: check.py); the
        table's own when m is n_table, for they are then the very same parameters."""
        self.curve = curve
        u = np.linspace(curve.u_min, curve.u_max, n_table)
        self.u_table = u
        # the points with their first two derivatives in one evaluation: the reference asks
        # for heading and curvature on this very table (path_arc_reference.py), and a lower
        # derivative comes out the same floats whatever n_ders (the Cox-de Boor triangle and
        # the quotient rule compute it alike)
        if samples is not None and samples.shape == (3, n_table, 2):
            self._table_ders = samples
        else:
            self._table_ders = curve.evaluate(u, n_ders=2)
        self.xy_table = self._table_ders[0]
        # arc length between consecutive table parameters by Gauss-Legendre, eq. (16)/(18)
        h = np.diff(u)
        uq = (u[:-1, None] + h[:, None] * _GL_X[None, :]).ravel()
        d1 = curve.evaluate(uq, n_ders=1)[1]
        speed = np.hypot(d1[:, 0], d1[:, 1]).reshape(-1, 3)
        seg = h * (speed @ _GL_W)
        self.s_table = np.concatenate([[0.0], np.cumsum(seg)])

    @property
    def length(self) -> float:
        return float(self.s_table[-1])

    def s_at_u(self, u: FloatArray | float) -> FloatArray:
        return np.asarray(np.interp(u, self.u_table, self.s_table), dtype=np.float64)

    def u_at_s(self, s: FloatArray | float) -> FloatArray:
        return np.asarray(np.interp(s, self.s_table, self.u_table), dtype=np.float64)

    def _ders_at(self, u: FloatArray | float, n_ders: int) -> FloatArray:
        """The curve's points and derivatives (at least n_ders + 1, m, 2) at u: those
        evaluated with the table when u is the table itself."""
        if u is self.u_table:
            return self._table_ders
        return self.curve.evaluate(np.atleast_1d(np.asarray(u, dtype=np.float64)), n_ders=n_ders)

    def point_at_u(self, u: FloatArray | float) -> FloatArray:
        return self._ders_at(u, 0)[0]

    def heading_at_u(self, u: FloatArray | float) -> FloatArray:
        d1 = self._ders_at(u, 1)[1]
        return np.arctan2(d1[:, 1], d1[:, 0])

    def curvature_at_u(self, u: FloatArray | float) -> FloatArray:
        """Unsigned curvature at u (eq. (20))."""
        d = self._ders_at(u, 2)
        return curvature(d[1], d[2])

    def signed_curvature_at_u(self, u: FloatArray | float) -> FloatArray:
        """Curvature with sign (> 0 turning left), as a path-following controller feeds forward."""
        d = self._ders_at(u, 2)
        cross = d[1][:, 0] * d[2][:, 1] - d[1][:, 1] * d[2][:, 0]
        speed3 = np.maximum(np.hypot(d[1][:, 0], d[1][:, 1]) ** 3, 1e-300)
        return np.asarray(cross / speed3)

    def closest_u(
        self,
        q: FloatArray,
        u_lo: float | None = None,
        u_hi: float | None = None,
        newton_iters: int = 4,
    ) -> tuple[float, float]:
        """Closest parameter u in [u_lo, u_hi] to point q, and the distance |C(u) - q| (m)."""
        lo = self.curve.u_min if u_lo is None else max(u_lo, self.curve.u_min)
        hi = self.curve.u_max if u_hi is None else min(u_hi, self.curve.u_max)
        q = np.asarray(q, dtype=np.float64).reshape(2)
        i0 = int(np.searchsorted(self.u_table, lo, side="left"))
        i1 = int(np.searchsorted(self.u_table, hi, side="right"))
        if i1 <= i0:  # window narrower than a table step: start from its middle
            u = 0.5 * (lo + hi)
        else:
            d2 = np.sum((self.xy_table[i0:i1] - q) ** 2, axis=1)
            u = float(self.u_table[i0 + int(np.argmin(d2))])
        for _ in range(newton_iters):
            c, d1, d2v = self.curve.evaluate(np.array([u]), n_ders=2)[:, 0, :]
            diff = c - q
            f = float(diff @ d1)
            fp = float(d1 @ d1 + diff @ d2v)
            if fp <= 0.0:
                break
            u_new = min(max(u - f / fp, lo), hi)
            if abs(u_new - u) < 1e-12:
                u = u_new
                break
            u = u_new
        c = self.curve.evaluate(np.array([u]), n_ders=0)[0, 0]
        return u, float(np.hypot(*(c - q)))
