"""Vehicle configuration: REMUS-100-like hull, eq. (11) bounds, actuators, watchdog.

Sources for the defaults (REMUS-100, Hydroid/Kongsberg):
- T. Prestero, "Verification of a six-degree of freedom simulation model for the REMUS
  autonomous underwater vehicle", MSc thesis, MIT/WHOI 2001: length 1.33-1.6 m (1.6 m with
  the usual payload sections), hull diameter 0.191 m, mass 30.5-31.9 kg, surge added mass
  X_udot = -0.93 kg (~3 %; we take 10 % to cover the entrained flow of fins and sensors).
- Hydroid REMUS-100 datasheet: max speed ~2.3 m/s (4.5 kn), typical 1.5 m/s (3 kn).
- ITTC-1957 friction line and a correlation allowance dCf = 4e-4 (ITTC 1978 practice for
  hydraulically rough model-scale hulls); seawater rho 1025 kg/m^3, nu 1.19e-6 m^2/s (15 C).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import ClassVar, Literal

from common.config.checks import int_range, nonneg, positive
from common.config.errors import ConfigValueError
from common.config.fossen import FossenConfig
from common.messages import MAX_SEQUENCE_LEN


@dataclass(frozen=True, kw_only=True)
class WatchdogConfig:
    """Command watchdog: reject stale/out-of-order commands, consume a command's sequence of
    future entries, HOLD then FAILSAFE when it runs out (services/vehicle/watchdog.py)."""

    # reject a command whose newest entry is older than this *beyond* the one-way delay the
    # vehicle measures (t_now - t_last > max_command_age_s + measured delay; t_last = stamp
    # for a single command), so a known delay is not mistaken for an outage
    max_command_age_s: float = 1.0
    # reject a command stamped further ahead of the vehicle's clock than this (clock skew
    # between processes is milliseconds; one command from the far future must not lock the
    # out-of-order check against every later command)
    max_future_s: float = 0.5
    hold_after_s: float = 2.0  # applied command older than this: HOLD (brake, w = 0)
    failsafe_after_s: float = 5.0  # older than this: report FAILSAFE until a fresh command
    # HOLD brakes. 0 (the default): the speed command drops to the floor (max(0, v_min_mps))
    # at once, so the speed loop brakes at the hull's limit (full reverse thrust plus drag,
    # at most accel_max_mps2); > 0: it falls at this rate (m/s^2), a gentler, longer stop.
    # The vehicle is blind from its last command: it runs hold_after_s on that command, then
    # brakes with the heading held; with the defaults, from 1.5 m/s: 3.0 m, then 5.4 m
    # (docs/notes/code-hold-brakes-at-hull-limit.md).
    hold_decel_mps2: float = 0.0
    # a command may carry at most this many future entries (the wire refuses more than
    # common.messages.MAX_SEQUENCE_LEN) spanning at most max_horizon_s past its stamp: at a
    # 0.1 s step, 20 s of predicted commands, enough to ride through a 20 s outage
    max_sequence_len: int = 200
    max_horizon_s: float = 30.0
    # commands whose delay the reported figure (median, MAD jitter) and the stale rule use
    delay_window: int = 31

    def __post_init__(self) -> None:
        int_range("max_sequence_len", self.max_sequence_len, 0, MAX_SEQUENCE_LEN)
        positive("max_horizon_s", self.max_horizon_s)
        int_range("delay_window", self.delay_window, 1, 10_000)
        positive("max_command_age_s", self.max_command_age_s)
        positive("max_future_s", self.max_future_s)
        positive("hold_after_s", self.hold_after_s)
        positive("failsafe_after_s", self.failsafe_after_s)
        nonneg("hold_decel_mps2", self.hold_decel_mps2)
        if self.hold_after_s < self.max_command_age_s:
            raise ConfigValueError(
                "hold_after_s",
                f"{self.hold_after_s!r} is below max_command_age_s "
                f"({self.max_command_age_s!r}), expected hold_after_s >= max_command_age_s",
            )
        if self.failsafe_after_s <= self.hold_after_s:
            raise ConfigValueError(
                "failsafe_after_s",
                f"{self.failsafe_after_s!r} must exceed hold_after_s ({self.hold_after_s!r})",
            )


@dataclass(frozen=True, kw_only=True)
class VehicleConfig:
    """The simulated vehicle: plant, eq. (11) bounds, actuator loops and watchdog."""

    # the plant (services/vehicle/plant.py): "unicycle", eq. (7) with lags and the turn
    # bounded by R_min (the planner's own model); "fossen3dof", the REMUS 100's surge, sway
    # and yaw with its propeller, rudder and autopilots ([fossen]; docs/vehicle-model.md),
    # whose turn nothing bounds but its hydrodynamics (a ~12 m circle at full rudder)
    model: Literal["unicycle", "fossen3dof"] = "unicycle"
    period_s: float = 0.05  # publishing period of truth and status
    dt_internal_s: float = 0.01  # fixed RK4 step (sub-stepped to exact delivery times)
    # eq. (11): bounds on surge speed v and yaw rate w. No reverse: v_min >= 0.
    v_min_mps: float = 0.0
    v_max_mps: float = 2.0
    w_min_rps: float = -0.5
    w_max_rps: float = 0.5
    accel_max_mps2: float = 0.3  # |dv/dt| bound ("must follow the rules of acceleration")
    yaw_accel_max_rps2: float = 0.5  # |dw/dt| bound
    cruise_speed_mps: float = 1.5  # v_ref: REMUS-100 survey speed (3 kn)
    # eq. (12) r: radius of the vehicle's bounding circle in the plane (half the length)
    radius_m: float = 0.8
    # minimum turning radius R_min of eqs. (19)-(20); REMUS-100 turns in ~10 m diameter.
    # The plant enforces it (|w| <= |v| / R_min at every instant: eq. (11)'s yaw-rate bound
    # made physical, so the vehicle cannot turn at rest); the planner and every controller
    # respect it.
    turn_radius_min_m: float = 5.0
    # hull (eq. 14): S = pi D L * wetted_fraction (the cylinder minus nose/tail taper)
    length_m: float = 1.6
    diameter_m: float = 0.19
    mass_kg: float = 31.9
    added_mass_ratio: float = 0.1  # surge added mass as a fraction of the mass
    wetted_fraction: float = 0.85
    rho_kgpm3: float = 1025.0
    nu_m2ps: float = 1.19e-6
    delta_cf: float = 4.0e-4  # eq. (14) dCf: roughness / correlation allowance (ITTC)
    # eq. (14) Cpv: viscous pressure (form) drag. A bare body of revolution with D/L = 0.12
    # has Hoerner's form factor k = 1.5 (D/L)^1.5 + 7 (D/L)^3 ~ 0.07, i.e. ~3e-4; fins, nose
    # transducers and the tail cone of a REMUS roughly triple it, hence 1e-3.
    c_pv: float = 1.0e-3
    # thrust bound: with the defaults R(2.05 m/s) = 9.1 N, so full thrust gives a steady top
    # speed of ~2.05 m/s, just above v_max (the speed loop can reach and hold v_max).
    thrust_max_n: float = 9.1
    thrust_min_n: float = -5.0  # reverse thrust for braking (the prop can back down)
    # inner speed loop: T = R(v_cmd) + kp (v_cmd - v) + ki int(v_cmd - v), bounded
    speed_kp_npmps: float = 35.0  # ~ m_eff / 1 s: 1 s speed time constant before limits
    # ki: half of critical damping ((kp + dR/dv)^2 / (4 m_eff) ~ 12 N/m); the drag
    # feed-forward already makes the steady state exact, so the integral only trims model
    # mismatch; a step from rest overshoots by < 1 % and settles in ~10 s.
    speed_ki_npm: float = 6.0
    # integration window: the integrand is weighted by exp(-((v_cmd - v) / band)^2)
    speed_int_band_mps: float = 0.05
    # yaw: first-order response of w towards the command, time constant yaw_tau_s
    yaw_tau_s: float = 0.5
    watchdog: WatchdogConfig = field(default_factory=WatchdogConfig)
    fossen: FossenConfig = field(default_factory=FossenConfig)  # vehicle.model = "fossen3dof"

    REMOVED_KEYS: ClassVar[Mapping[str, str]] = {
        "current": "the current moved to world.current, the same water for every vehicle "
        "(speed_mps, direction_deg, shear_mps, eddies, tidal_period_s, sigma_mps, tau_s, "
        "update_s; x_mps and y_mps become speed_mps and direction_deg)",
    }

    def __post_init__(self) -> None:
        if self.model not in ("unicycle", "fossen3dof"):
            raise ConfigValueError("model", f"{self.model!r}, expected 'unicycle' or 'fossen3dof'")
        for name in (
            "period_s", "dt_internal_s", "v_max_mps", "w_max_rps", "accel_max_mps2",
            "yaw_accel_max_rps2", "cruise_speed_mps", "radius_m", "turn_radius_min_m",
            "length_m", "diameter_m", "mass_kg", "wetted_fraction", "rho_kgpm3", "nu_m2ps",
            "thrust_max_n", "yaw_tau_s", "speed_kp_npmps", "speed_int_band_mps",
        ):  # fmt: skip
            positive(name, getattr(self, name))
        for name in (
            "v_min_mps", "added_mass_ratio", "delta_cf", "c_pv", "speed_ki_npm",
        ):  # fmt: skip
            nonneg(name, getattr(self, name))
        if self.v_min_mps >= self.v_max_mps:
            raise ConfigValueError(
                "v_min_mps", f"{self.v_min_mps!r} must be below v_max_mps ({self.v_max_mps!r})"
            )
        if not (math.isfinite(self.w_min_rps) and self.w_min_rps < 0.0):
            raise ConfigValueError(
                "w_min_rps", f"{self.w_min_rps!r} is invalid, expected a value < 0"
            )
        if not (self.v_min_mps <= self.cruise_speed_mps <= self.v_max_mps):
            raise ConfigValueError(
                "cruise_speed_mps",
                f"{self.cruise_speed_mps!r} is outside [v_min_mps, v_max_mps] "
                f"= [{self.v_min_mps!r}, {self.v_max_mps!r}]",
            )
        if self.cruise_speed_mps / self.turn_radius_min_m > min(self.w_max_rps, -self.w_min_rps):
            raise ConfigValueError(
                "turn_radius_min_m",
                f"{self.turn_radius_min_m!r} is too tight: turning on it at "
                f"cruise speed needs a yaw rate above the eq. (11) bound, expected "
                f"R_min >= cruise_speed_mps / min(w_max_rps, -w_min_rps)",
            )
        if self.wetted_fraction > 1.0:
            raise ConfigValueError("wetted_fraction", f"{self.wetted_fraction!r} must be <= 1")
        if not (math.isfinite(self.thrust_min_n) and self.thrust_min_n <= 0.0):
            raise ConfigValueError(
                "thrust_min_n", f"{self.thrust_min_n!r} is invalid, expected <= 0"
            )
        if self.dt_internal_s > self.period_s:
            raise ConfigValueError(
                "dt_internal_s", f"{self.dt_internal_s!r} exceeds period_s ({self.period_s!r})"
            )

    @property
    def wetted_area_m2(self) -> float:
        """Wetted surface S of eq. (14): pi D L times the wetted fraction."""
        return math.pi * self.diameter_m * self.length_m * self.wetted_fraction

    @property
    def mass_eff_kg(self) -> float:
        """Surge inertia including added mass."""
        return self.mass_kg * (1.0 + self.added_mass_ratio)
