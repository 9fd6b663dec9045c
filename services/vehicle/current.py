"""Ocean current: a constant drift plus a first-order Gauss-Markov process per axis.

The Gauss-Markov part is sampled exactly at knots every `update_s` (a whole number of internal
steps) and linearly interpolated between them. Knots are drawn in time order from the seeded
generator, so the current is a function of (time, seed) only: it does not depend on when
commands happen to arrive, which keeps the plant independent of the delivery pattern.
"""

from __future__ import annotations

import math

import numpy as np

from common.config.vehicle import CurrentConfig


class OceanCurrent:
    """Current velocity (cx, cy) in m/s over the world frame, advecting the vehicle position."""

    def __init__(self, cfg: CurrentConfig, dt_internal_s: float, rng: np.random.Generator) -> None:
        self._cfg = cfg
        self._dt = dt_internal_s
        self._n = max(1, round(cfg.update_s / dt_internal_s))  # internal steps per knot
        self._rng = rng
        # exact discretisation of db = -b/tau dt + sigma sqrt(2/tau) dW over one knot spacing
        self._phi = math.exp(-cfg.update_s / cfg.tau_s)
        self._gain = cfg.sigma_mps * math.sqrt(1.0 - self._phi * self._phi)
        self._j = 0  # index of the first stored knot
        if cfg.sigma_mps > 0.0:
            b0 = self._draw(cfg.sigma_mps)  # start in the stationary distribution
            self._knots = [b0, self._next(b0)]
        else:
            self._knots = [(0.0, 0.0), (0.0, 0.0)]

    def _draw(self, scale: float) -> tuple[float, float]:
        n = self._rng.standard_normal(2)
        return scale * float(n[0]), scale * float(n[1])

    def _next(self, b: tuple[float, float]) -> tuple[float, float]:
        dx, dy = self._draw(self._gain)
        return self._phi * b[0] + dx, self._phi * b[1] + dy

    def segment(self, k: int, t0: float) -> tuple[float, float, float, float]:
        """Current over internal grid cell k ([k dt, (k+1) dt]) from time t0 in that cell.

        Returns (cx(t0), cy(t0), dcx/dt, dcy/dt): the current is linear across the cell.
        """
        c = self._cfg
        if c.sigma_mps == 0.0:
            return c.x_mps, c.y_mps, 0.0, 0.0
        j = k // self._n
        if j < self._j:
            raise ValueError(f"current: grid cell {k} lies before the stored knots (time ran back)")
        while self._j < j:  # advance the knot pair; never revisits the past
            self._knots = [self._knots[1], self._next(self._knots[1])]
            self._j += 1
        (bx0, by0), (bx1, by1) = self._knots
        span = self._n * self._dt
        sx, sy = (bx1 - bx0) / span, (by1 - by0) / span
        tau = t0 - (j * self._n) * self._dt
        return c.x_mps + bx0 + sx * tau, c.y_mps + by0 + sy * tau, sx, sy
