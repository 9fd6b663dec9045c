"""Path-tracking controller configuration: which controller, its gains, delay compensation.

The eq. (11) bounds, R_min and the cruise speed are not here: they are the vehicle's
(common/config/vehicle.py) and are handed to the controllers as `Limits`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

from common.config.checks import fraction, nonneg, positive
from common.config.errors import ConfigValueError

ControllerKind = Literal["nurbs", "backstepping", "fuzzy_pid"]


@dataclass(frozen=True, kw_only=True)
class NurbsGains:
    """NurbsTracker: curvature feed-forward + look-ahead (LOS) cross-track/heading feedback."""

    lookahead_m: float = 3.0  # minimum look-ahead distance Delta of the approach angle
    lookahead_time_s: float = 1.5  # Delta = max(lookahead_m, lookahead_time_s * v)
    k_heading_ps: float = 1.2  # heading-error gain (1/s)
    # share of the yaw-rate bound the feed-forward v*kappa may use; the rest is for feedback
    curvature_budget: float = 0.7
    preview_s: float = 3.0  # speed is reduced for the tightest curvature this far ahead

    def __post_init__(self) -> None:
        for name in ("lookahead_m", "k_heading_ps"):
            positive(name, getattr(self, name))
        for name in ("lookahead_time_s", "preview_s"):
            nonneg(name, getattr(self, name))
        fraction("curvature_budget", self.curvature_budget)


@dataclass(frozen=True, kw_only=True)
class BacksteppingGains:
    """Kanayama et al. (1990) tracking law gains; k_theta = 2 sqrt(k_y) is critical damping."""

    k_x_ps: float = 0.5  # along-track gain (1/s)
    k_y_pm2: float = 0.04  # cross-track gain (1/m^2): omega_n = v_r sqrt(k_y) = 0.3 rad/s
    k_theta_pm: float = 0.4  # heading gain (1/m)
    max_lead_m: float = 5.0  # the virtual reference point runs at most this far ahead

    def __post_init__(self) -> None:
        for name in ("k_x_ps", "k_y_pm2", "k_theta_pm", "max_lead_m"):
            positive(name, getattr(self, name))


@dataclass(frozen=True, kw_only=True)
class FuzzyPidGains:
    """Immune fuzzy PID on the combined (LOS) heading error; output yaw rate."""

    kp_ps: float = 1.0  # base proportional gain (rad/s per rad)
    ki_ps2: float = 0.15  # base integral gain
    kd: float = 0.15  # base derivative gain (s)
    dkp_ps: float = 0.5  # fuzzy adaptation range: Kp in kp +- dkp
    dki_ps2: float = 0.05
    dkd: float = 0.05
    e_scale_rad: float = 0.6  # |e| mapped to the NB/PB ends of the input universe
    de_scale_rps: float = 0.6  # |de/dt| mapped to the NB/PB ends
    de_filter_s: float = 0.2  # eq. (3) first-order lag on de/dt (virtual damping)
    lookahead_m: float = 4.0  # cross-track -> heading: desired heading offset -atan(e_y/L)
    immune_k1: float = 1.0  # immune gain K1
    immune_eta: float = 0.4  # suppression strength eta, < 1 keeps the gain positive
    immune_a: float = 0.01  # f(du) = 1 - exp(-du^2 / a), a in (rad/s)^2
    slow_k: float = 1.0  # v = v_ref / (1 + slow_k |e|)
    v_floor_ratio: float = 0.4  # ... but at least this share of v_ref

    def __post_init__(self) -> None:
        for name in ("kp_ps", "e_scale_rad", "de_scale_rps", "lookahead_m", "immune_k1"):
            positive(name, getattr(self, name))
        for name in ("ki_ps2", "kd", "dkp_ps", "dki_ps2", "dkd", "de_filter_s", "slow_k"):
            nonneg(name, getattr(self, name))
        positive("immune_a", self.immune_a)
        if not (0.0 <= self.immune_eta < 1.0):
            raise ConfigValueError("immune_eta", f"{self.immune_eta!r} is invalid, expected [0, 1)")
        fraction("v_floor_ratio", self.v_floor_ratio)


@dataclass(frozen=True, kw_only=True)
class ControllerConfig:
    """Which path-tracking controller the planner runs, and every controller's gains."""

    kind: ControllerKind = "nurbs"
    # predict the pose forward by the measured estimate age + expected downlink delay
    # before computing (the NURBS method's delay compensation)
    delay_compensation: bool = True
    # also give the two baselines that prediction (off: they run as published, which is the
    # comparison the paper makes; on: isolates the control law from the compensation)
    compensate_baselines: bool = False
    nurbs: NurbsGains = field(default_factory=NurbsGains)
    backstepping: BacksteppingGains = field(default_factory=BacksteppingGains)
    fuzzy_pid: FuzzyPidGains = field(default_factory=FuzzyPidGains)

    def __post_init__(self) -> None:
        if self.kind not in ("nurbs", "backstepping", "fuzzy_pid"):
            raise ConfigValueError(
                "kind", f"{self.kind!r} is unknown, expected 'nurbs', 'backstepping' or 'fuzzy_pid'"
            )
