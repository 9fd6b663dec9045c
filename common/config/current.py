"""Ocean current configuration: `[world.current]`, the water every vehicle of a run moves in.

The current is part of the world (common/world/current.py `CurrentField` evaluates it), the
same for every vehicle of a fleet, a pure function of position, time and the run's seed:

    c(x, y, t) = f(t) (U + S s(x, y) / (2 W)) d  +  sum of Gaussian eddies  +  b(t)

- d = (cos phi, sin phi): the direction the water flows towards, counter-clockwise from +x
  (east), like the project's headings; `direction = "seeded"` draws phi from the run's seed;
- U the uniform speed; S a linear shear across the flow: s is the signed distance from the
  area's centre line along the left normal of d, W the area's half-width across the flow, so
  the along-flow speed is U + S/2 on the left edge and U - S/2 on the right (held at those
  values beyond the area);
- f(t) = 1 + A sin(2 pi t / P + phase): a tide scaling the uniform and shear part (1 without);
- each eddy a Gaussian vortex (non-divergent): tangential speed V (r/R) exp((1 - r^2/R^2)/2),
  peak V at r = R, counter-clockwise for V > 0;
- b(t) a first-order Gauss-Markov process per axis (gusts), uniform in space:
  db = -b/tau dt + sigma sqrt(2/tau) dW, stationary std sigma, sampled exactly every update_s
  and linearly interpolated in between.

Every part is off by default: the default current is calm, and costs nothing.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.checks import nonneg, positive
from common.config.errors import ConfigValueError

DirectionMode = Literal["fixed", "seeded"]


@dataclass(frozen=True, kw_only=True)
class EddyConfig:
    """A Gaussian eddy: a vortex of peak tangential speed speed_mps at radius_m from its centre."""

    x_m: float  # centre, world x (east)
    y_m: float  # centre, world y (north)
    radius_m: float  # R: where the tangential speed peaks; it falls off as exp(-r^2 / 2R^2)
    speed_mps: float  # V: peak tangential speed (at r = R); > 0 counter-clockwise, < 0 clockwise

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "speed_mps"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(name, f"{getattr(self, name)!r} is not a finite number")
        positive("radius_m", self.radius_m)


@dataclass(frozen=True, kw_only=True)
class CurrentConfig:
    """Ocean current: uniform flow, linear shear, Gaussian eddies, a tide and Gauss-Markov gusts."""

    speed_mps: float = 0.0  # U: speed of the uniform flow (>= 0)
    # phi: the direction the uniform flow goes towards, degrees counter-clockwise from +x
    # (east): 90 flows north. Ignored when direction = "seeded".
    direction_deg: float = 0.0
    # "fixed": phi = direction_deg; "seeded": phi drawn uniformly in [0, 360) from run.seed
    # (the same for every vehicle of the run, another for another seed)
    direction: DirectionMode = "fixed"
    # S: linear shear across the flow: the along-flow speed is U + S/2 on the area's left edge
    # (looking downstream) and U - S/2 on its right edge, U on the centre line; signed
    shear_mps: float = 0.0
    eddies: tuple[EddyConfig, ...] = ()  # Gaussian eddies ([[world.current.eddies]])
    # P: tidal period; the uniform and shear part is scaled by
    # 1 + tidal_amplitude * sin(2 pi t / P + tidal_phase_rad). 0 = no tide.
    tidal_period_s: float = 0.0
    # A (>= 0, needs tidal_period_s > 0): above 1 the flow reverses for part of each period
    tidal_amplitude: float = 0.0
    tidal_phase_rad: float = 0.0  # tide phase at t = 0
    sigma_mps: float = 0.0  # gusts: stationary std of the Gauss-Markov part, per axis (0 = off)
    tau_s: float = 120.0  # gusts: correlation time
    update_s: float = 1.0  # gusts: knot spacing (exact samples, linear in between)

    def __post_init__(self) -> None:
        nonneg("speed_mps", self.speed_mps)
        for name in ("direction_deg", "shear_mps", "tidal_phase_rad"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(name, f"{getattr(self, name)!r} is not a finite number")
        if self.direction not in ("fixed", "seeded"):
            raise ConfigValueError(
                "direction", f"{self.direction!r} is unknown, expected 'fixed' or 'seeded'"
            )
        nonneg("tidal_period_s", self.tidal_period_s)
        nonneg("tidal_amplitude", self.tidal_amplitude)
        if self.tidal_amplitude > 0.0 and self.tidal_period_s == 0.0:
            raise ConfigValueError(
                "tidal_amplitude",
                f"{self.tidal_amplitude!r} without a tide: set tidal_period_s > 0 too",
            )
        nonneg("sigma_mps", self.sigma_mps)
        positive("tau_s", self.tau_s)
        positive("update_s", self.update_s)

    @property
    def is_calm(self) -> bool:
        """No current anywhere, ever: every part is off."""
        return (
            self.speed_mps == 0.0
            and self.shear_mps == 0.0
            and not any(e.speed_mps for e in self.eddies)
            and self.sigma_mps == 0.0
        )
