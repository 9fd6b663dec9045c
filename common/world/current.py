"""The ocean current as a field over the world: c(x, y, t) in m/s, the same for every vehicle.

    c(x, y, t) = f(t) (U + S s / (2 W)) d  +  sum_i eddy_i(x, y)  +  b(t)

(the terms are those of common/config/current.py). Each eddy is a Gaussian vortex, the
velocity of the stream function psi = -V R sqrt(e) exp(-r^2 / 2R^2), i.e. tangential speed
V (r/R) exp((1 - r^2/R^2) / 2): non-divergent, peak V at r = R. The uniform flow and the shear
across it are non-divergent too, so the water neither piles up nor empties anywhere.

The field is a pure function of (x, y, t) and the run's seed: the seeded direction and the
gusts' knots come from the counter-based RNG of common/netmodel/rng.py (keyed by the seed and
the labels "world/current/direction" and "world/current"), not from a generator whose output
depends on how many draws came before. The gust knots b_j (every update_s, exact AR(1)
discretisation of the Gauss-Markov process, b_0 drawn from its stationary law) are computed
lazily in index order and cached, so any order of queries gives the same floats: lockstep and
inproc runs, and every vehicle of a fleet, feel the same water bit for bit.

Cost (per velocity() call, beyond the call itself): nothing for a calm field (callers skip
it: `is_calm`), a tuple for a uniform one, one exp per eddy and a knot lookup for the rest.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
from numpy.typing import ArrayLike, NDArray

from common.config.current import CurrentConfig
from common.config.world import AreaConfig
from common.netmodel.rng import CounterRng

# (x_m, y_m, t_s) -> (cx, cy) m/s in the world frame: what a plant asks of the water
CurrentFn = Callable[[float, float, float], tuple[float, float]]

DIRECTION_LINK = "world/current/direction"  # the seeded direction: uniform 0 of seq 0
GUST_LINK = "world/current"  # gust knot j: uniforms 0 and 1 of seq j (Box-Muller)
GUST_SIGMAS = 6.0  # speed_bound_mps counts gusts up to this many stationary stds per axis


def unit_vector(direction_deg: float) -> tuple[float, float]:
    """(cos, sin) of a direction in degrees; exact (0, +-1, ...) at multiples of 90 degrees."""
    d = direction_deg % 360.0
    exact = {0.0: (1.0, 0.0), 90.0: (0.0, 1.0), 180.0: (-1.0, 0.0), 270.0: (0.0, -1.0)}
    if d in exact:
        return exact[d]
    r = math.radians(d)
    return math.cos(r), math.sin(r)


def seeded_direction_deg(seed: int) -> float:
    """The direction (degrees in [0, 360)) that `direction = "seeded"` draws for a seed."""
    return 360.0 * CounterRng(seed=seed, link=DIRECTION_LINK).uniforms(0)[0]


class CurrentField:
    """The current of one run over its area: velocity(x, y, t), cheap and deterministic."""

    def __init__(self, cfg: CurrentConfig, area: AreaConfig, seed: int) -> None:
        self.config = cfg
        self.seed = seed
        self.direction_deg = (
            seeded_direction_deg(seed) if cfg.direction == "seeded" else cfg.direction_deg % 360.0
        )
        dx, dy = unit_vector(self.direction_deg)
        self._dx, self._dy = dx, dy
        self._speed = cfg.speed_mps
        self._uniform = (cfg.speed_mps * dx, cfg.speed_mps * dy)
        # shear: s = (p - centre) . n with n = (-dy, dx) the left normal, |s| <= W on the area
        self._xc = 0.5 * (area.x_min_m + area.x_max_m)
        self._yc = 0.5 * (area.y_min_m + area.y_max_m)
        half_w = 0.5 * (
            (area.x_max_m - area.x_min_m) * abs(dy) + (area.y_max_m - area.y_min_m) * abs(dx)
        )
        self._half_w = half_w
        self._shear_k = cfg.shear_mps / (2.0 * half_w)  # along-flow speed change per metre
        self._tide = cfg.tidal_period_s > 0.0 and cfg.tidal_amplitude > 0.0
        self._tide_w = 2.0 * math.pi / cfg.tidal_period_s if self._tide else 0.0
        # eddy i: (x, y, V/R sqrt(e), 1 / 2R^2): u_theta / r = V/R sqrt(e) exp(-r^2 / 2R^2)
        self._eddies = tuple(
            (e.x_m, e.y_m, e.speed_mps / e.radius_m * math.exp(0.5), 0.5 / e.radius_m**2)
            for e in cfg.eddies
            if e.speed_mps != 0.0
        )
        # gusts: b_j = phi b_{j-1} + sigma sqrt(1 - phi^2) z_j, b_0 = sigma z_0
        self._gusts = cfg.sigma_mps > 0.0
        self._update_s = cfg.update_s
        self._phi = math.exp(-cfg.update_s / cfg.tau_s)
        self._gain = cfg.sigma_mps * math.sqrt(1.0 - self._phi * self._phi)
        self._rng = CounterRng(seed=seed, link=GUST_LINK) if self._gusts else None
        self._bx: list[float] = []
        self._by: list[float] = []
        self.is_calm = cfg.is_calm
        # the cheapest evaluation that is exact for this field, chosen once
        only_uniform = cfg.shear_mps == 0.0 and not self._tide
        only_uniform = only_uniform and not self._eddies and not self._gusts
        self.velocity: CurrentFn = (
            self._calm if self.is_calm else self._flat if only_uniform else self._general()
        )

    # -- evaluation ----------------------------------------------------------------------------

    def _calm(self, x: float, y: float, t: float) -> tuple[float, float]:
        return 0.0, 0.0

    def _flat(self, x: float, y: float, t: float) -> tuple[float, float]:
        return self._uniform

    def _general(self) -> CurrentFn:
        """velocity() of a field with shear, tide, eddies or gusts: a closure over the field's
        constants (a closure's variables are read faster than attributes: ~0.2 us a call)."""
        c = self.config
        dx, dy, xc, yc, half_w = self._dx, self._dy, self._xc, self._yc, self._half_w
        speed, shear_k, shear = self._speed, self._shear_k, c.shear_mps != 0.0
        tide, amp, omega, phase = self._tide, c.tidal_amplitude, self._tide_w, c.tidal_phase_rad
        eddies, gusts, update_s = self._eddies, self._gusts, self._update_s
        bx, by, knots_to = self._bx, self._by, self._knots_to  # the knot cache, grown in place
        exp, sin = math.exp, math.sin

        def velocity(x: float, y: float, t: float) -> tuple[float, float]:
            along = speed
            if shear:  # linear across the flow, held beyond the area's edges
                s = (y - yc) * dx - (x - xc) * dy
                along += shear_k * (half_w if s > half_w else -half_w if s < -half_w else s)
            if tide:  # f(t) = 1 + A sin(2 pi t / P + phase)
                along *= 1.0 + amp * sin(omega * t + phase)
            cx, cy = along * dx, along * dy
            for ex, ey, a, k in eddies:  # u = -g (y - ey), v = g (x - ex): counter-clockwise
                rx, ry = x - ex, y - ey
                g = a * exp(-(rx * rx + ry * ry) * k)
                cx -= g * ry
                cy += g * rx
            if gusts:  # as gust(t), inlined
                q = t / update_s
                if q > 0.0:
                    j = int(q)
                    f = q - j
                    if j + 1 >= len(bx):
                        knots_to(j + 1)
                    cx += bx[j] + (bx[j + 1] - bx[j]) * f
                    cy += by[j] + (by[j + 1] - by[j]) * f
                else:
                    knots_to(0)
                    cx += bx[0]
                    cy += by[0]
            return cx, cy

        return velocity

    def gust(self, t: float) -> tuple[float, float]:
        """The Gauss-Markov part b(t): linear between the knots b_j at t = j update_s (b_0
        before t = 0); (0, 0) without gusts."""
        if not self._gusts:
            return 0.0, 0.0
        q = t / self._update_s
        if not q > 0.0:
            self._knots_to(0)
            return self._bx[0], self._by[0]
        j = int(q)
        frac = q - j
        if j + 1 >= len(self._bx):
            self._knots_to(j + 1)
        bx, by = self._bx, self._by
        return bx[j] + (bx[j + 1] - bx[j]) * frac, by[j] + (by[j + 1] - by[j]) * frac

    def _knots_to(self, j: int) -> None:
        """Extend the cached knots through index j, in index order (so the cache never
        depends on the order of queries)."""
        rng = self._rng
        assert rng is not None
        bx, by = self._bx, self._by
        while len(bx) <= j:
            n = len(bx)
            u0, u1 = rng.uniforms(n)[:2]
            r = math.sqrt(-2.0 * math.log(1.0 - u0))  # Box-Muller: 1 - u0 in (0, 1]
            zx, zy = r * math.cos(2.0 * math.pi * u1), r * math.sin(2.0 * math.pi * u1)
            if n == 0:  # start in the stationary distribution
                sigma = self.config.sigma_mps
                bx.append(sigma * zx)
                by.append(sigma * zy)
            else:
                bx.append(self._phi * bx[-1] + self._gain * zx)
                by.append(self._phi * by[-1] + self._gain * zy)

    # -- summaries -----------------------------------------------------------------------------

    def speed_bound_mps(self) -> float:
        """An upper bound of |c| over the area and the run: the uniform flow plus half the
        shear, times the tide's largest factor 1 + A, plus every eddy's peak, plus
        GUST_SIGMAS stationary stds of the gusts on each axis (6 sqrt(2) sigma)."""
        c = self.config
        tide = 1.0 + c.tidal_amplitude if self._tide else 1.0
        flow = (c.speed_mps + 0.5 * abs(c.shear_mps)) * tide
        eddies = sum(abs(e.speed_mps) for e in c.eddies)
        return flow + eddies + GUST_SIGMAS * math.sqrt(2.0) * c.sigma_mps

    def sample(
        self, t: float, xs: ArrayLike, ys: ArrayLike
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """The current at points (xs, ys) (any one shape) at time t: (u, v) arrays of that
        shape, the very floats velocity() gives (for a quiver plot, or a test)."""
        x = np.asarray(xs, dtype=np.float64)
        y = np.asarray(ys, dtype=np.float64)
        u, v = np.zeros(x.shape), np.zeros(x.shape)
        for i in np.ndindex(x.shape):
            u[i], v[i] = self.velocity(float(x[i]), float(y[i]), t)
        return u, v
