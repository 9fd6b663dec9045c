"""The planned NURBS path seen by a tracking controller: the Reference protocol by arc length."""

from __future__ import annotations

import numpy as np

from services.planner.nurbs_path import NurbsPath


class NurbsReference:
    """Adapts a NurbsPath (parameter u) to the controllers' Reference (arc length s)."""

    # the projection searches this window around the previous one, so the controller never
    # jumps to another leg of a path that comes back near itself
    BEHIND_M = 5.0
    AHEAD_M = 15.0

    def __init__(self, path: NurbsPath, v_ref: float) -> None:
        self.path = path
        self._v_ref = v_ref
        # controllers preview curvature at many points per step: tabulate it once per path
        # on the path's dense parameter table (a few cm apart) and interpolate
        self._k_table = path.signed_curvature(path.u_table)

    @property
    def length(self) -> float:
        return self.path.length

    @property
    def v_ref(self) -> float:
        return self._v_ref

    def _u(self, s: float) -> float:
        return float(self.path.u_of_s(np.array([min(max(s, 0.0), self.length)]))[0])

    def project(self, x: float, y: float, s_hint: float | None) -> float:
        if s_hint is None:
            u, _ = self.path.project(np.array([x, y]))
        else:
            u, _ = self.path.project(
                np.array([x, y]), self._u(s_hint - self.BEHIND_M), self._u(s_hint + self.AHEAD_M)
            )
        return float(self.path.s_of_u(np.array([u]))[0])

    def point(self, s: float) -> tuple[float, float]:
        p = self.path.point(np.array([self._u(s)]))[0]
        return float(p[0]), float(p[1])

    def heading(self, s: float) -> float:
        return float(self.path.heading(np.array([self._u(s)]))[0])

    def curvature(self, s: float) -> float:
        return float(np.interp(s, self.path.s_table, self._k_table))
