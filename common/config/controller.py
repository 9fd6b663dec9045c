"""Path-tracking controller configuration: which controller, its gains, the shared speed
profile, delay compensation and predictive command sequences.

The eq. (11) bounds, R_min and the cruise speed are not here: they are the vehicle's
(common/config/vehicle.py) and are handed to the controllers as `Limits`. A key that was
removed is listed in its table's REMOVED_KEYS with the reason: a scenario that still sets it
gets that reason as a config error (common/config/loader.py), not a bare "unknown key".
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field, fields
from typing import ClassVar, Literal

from common.config.checks import fraction, nonneg, positive
from common.config.errors import ConfigValueError

ControllerKind = Literal["nurbs", "backstepping", "fuzzy_pid"]


@dataclass(frozen=True, kw_only=True)
class NurbsGains:
    """NurbsTracker: curvature feed-forward + look-ahead (LOS) cross-track/heading feedback."""

    lookahead_m: float = 3.0  # minimum look-ahead distance Delta of the approach angle
    lookahead_time_s: float = 1.5  # Delta = max(lookahead_m, lookahead_time_s * v)
    k_heading_ps: float = 1.2  # heading-error gain (1/s)

    REMOVED_KEYS: ClassVar[Mapping[str, str]] = {
        "curvature_budget": "the curvature slow-down is shared by every controller now: "
        "use controller.speed.curvature_budget",
        "preview_s": "the curvature slow-down is shared by every controller now: "
        "use controller.speed.preview_s",
    }

    def __post_init__(self) -> None:
        for name in ("lookahead_m", "k_heading_ps"):
            positive(name, getattr(self, name))
        nonneg("lookahead_time_s", self.lookahead_time_s)


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

    REMOVED_KEYS: ClassVar[Mapping[str, str]] = dict.fromkeys(
        ("slow_k", "v_floor_ratio"),
        "the speed law v = v_ref / (1 + slow_k |e|) is not from the immune fuzzy PID "
        "literature and made travel times measure speed policy, not steering; every "
        "controller follows the shared speed profile now (controller.speed)",
    )

    def __post_init__(self) -> None:
        for name in ("kp_ps", "e_scale_rad", "de_scale_rps", "lookahead_m", "immune_k1"):
            positive(name, getattr(self, name))
        for name in ("ki_ps2", "kd", "dkp_ps", "dki_ps2", "dkd", "de_filter_s"):
            nonneg(name, getattr(self, name))
        positive("immune_a", self.immune_a)
        if not (0.0 <= self.immune_eta < 1.0):
            raise ConfigValueError("immune_eta", f"{self.immune_eta!r} is invalid, expected [0, 1)")


@dataclass(frozen=True, kw_only=True)
class SpeedConfig:
    """The speed profile every controller follows (services/control/controllers/speed.py).

    Cruise: the path's v_ref within eq. (11). Ramp: from the vehicle's speed when a path is
    taken (or the last command's ramp, if at most ramp_carry_s old and faster), the
    commanded speed rises at most accel_mps2. Slow-downs: v |kappa| <= budget *
    w_max over the curvature preview window, and v <= sqrt(2 decel_mps2 d) with d the arc
    length left to the end of the path (a stop at the goal).
    """

    # the commanded speed rises at most this fast; below the hull's 0.3 m/s^2 so that the
    # speed loop follows the ramp instead of saturating behind it
    accel_mps2: float = 0.2
    decel_mps2: float = 0.2  # the stop at the end of the path: v <= sqrt(2 decel d_left)
    # share of the eq. (11) yaw-rate bound the curvature feed-forward v |kappa| may take at
    # the tightest curvature ahead; the rest is left to the feedback
    curvature_budget: float = 0.7
    preview_s: float = 3.0  # the curvature slow-down looks this far ahead (at cruise speed)
    # in a current the stop at the end of the path keeps this many times the current's speed
    # (at most cruise): a vehicle slower than the current it crabs in drifts off its path
    # instead of arriving (the mission ends on arrival, within the goal tolerance)
    steerage_per_current: float = 2.0
    # a path taken at most this long (s) after the last speed command carries on with that
    # command's ramp when it is faster than the vehicle: the hull's speed lags the command,
    # and a ramp restarted from it at every replan barely accelerates (0 = always restart)
    ramp_carry_s: float = 0.5

    def __post_init__(self) -> None:
        for name in ("accel_mps2", "decel_mps2"):
            positive(name, getattr(self, name))
        nonneg("preview_s", self.preview_s)
        nonneg("ramp_carry_s", self.ramp_carry_s)
        nonneg("steerage_per_current", self.steerage_per_current)
        fraction("curvature_budget", self.curvature_budget)


@dataclass(frozen=True, kw_only=True)
class SequenceConfig:
    """Packet-based predictive commands (services/control/command/sequence.py): every command
    carries the controller's commands for the times ahead, one per control period
    (planner.period_s), computed on the state predicted along them; the vehicle applies the one
    for its time."""

    # how far ahead a command reaches (s); 0 = off: single commands, each computed from the
    # estimate as before sequences existed (the ablation). 10 s of buffer carry the vehicle
    # through a 10 s outage on the path it was following (at 0.1 s, 100 entries, ~0.4 kB)
    horizon_s: float = 10.0
    # the last entries bring the vehicle to rest on its path (speeds capped at the hull's
    # acceleration bound times the time left in the horizon): a buffer that runs out leaves
    # it stopped where its path goes, not running on blind then braking heading-held (HOLD)
    stop_tail: bool = True
    # how long past the next command's expected arrival the entries are computed in the step,
    # on the newest state (s): they are what the vehicle applies while the next command is
    # late or lost up to this long. The later ones are taken from the sequence prepared after
    # the step before, once its command was out (a prediction one period older), so a command
    # goes out after a few controller evaluations instead of one per entry. >= horizon_s:
    # every entry in the step (sequence.py, "Prepared tails")
    fresh_s: float = 0.5
    # a prepared tail is reused, shifted by one period, instead of rolled out again after the
    # step, while the newest prediction agrees with it where the step's fresh entries end
    # (pose and commands within the tolerances below): a tail at most reuse_s older than
    # the fresh entries. 0: a tail rolled out after every step (sequence.py, "Reused tails").
    # The state's bounds set how far a blind run on the tail may start off it (docs/notes/0067)
    reuse_s: float = 1.0
    reuse_tolerance_m: float = 0.1  # position
    reuse_tolerance_rad: float = 0.02  # heading
    reuse_tolerance_rate_rps: float = 0.04  # yaw rate, state and command
    reuse_tolerance_mps: float = 0.03  # speed, state and command
    # entries up to fine_s ahead are each the controller's answer to the state predicted for
    # their time; beyond, it is asked every coarse_step_s (whole periods) and its answer held
    # over the entries between. Those entries are applied only blind, in an outage longer
    # than fine_s, and the rollout still carries the state over each of them under what it
    # holds (sequence.py, "Coarse far entries"). fine_s >= horizon_s: every entry asked
    fine_s: float = 3.0
    coarse_step_s: float = 0.3

    def __post_init__(self) -> None:
        for f in fields(self):  # every time, tolerance and step: finite, >= 0
            if f.type == "float":
                nonneg(f.name, getattr(self, f.name))

    def entries(self, period_s: float) -> int:
        """Future entries n of a command at control period period_s (0: off)."""
        return int(self.horizon_s / period_s + 1e-9)

    def coarse(self, period_s: float) -> tuple[int, int]:
        """(k, m) at control period period_s: entries past k are asked every m-th (m >= 1)."""
        return int(self.fine_s / period_s + 1e-9), max(1, int(self.coarse_step_s / period_s + 1e-9))


@dataclass(frozen=True, kw_only=True)
class ControllerConfig:
    """Which path-tracking controller the planner runs, what all share, and each one's gains.

    Shared by every controller: the speed profile (`speed`), the delay compensation and the
    predictive command sequences (`sequence`), so that the three differ in how they steer only.
    """

    kind: ControllerKind = "nurbs"
    # where the controller runs: "planner" (with the planner, commands cross the network to
    # the vehicle) or "onboard" (a tracker service on the vehicle's node follows the newest
    # path the planner sent, from the onboard estimate: only paths cross the network)
    placement: Literal["planner", "onboard"] = "planner"
    # every controller works on the state predicted to the time its command takes effect, the
    # estimate's age plus the downlink delay on (on), or on the estimate as it is (off)
    delay_compensation: bool = True
    # the downlink delay compensated: the vehicle's measured median one-way command delay
    # plus this many of its measured jitters (1.4826 MAD, VehicleStatus); the network's
    # configured delay of planner/cmd until the vehicle has measured one. 0: a sequence's
    # entries are time-stamped, so the planner should expect it to take over at the median
    # delay, not later (docs/notes/code-jitter-margin-zero.md)
    jitter_margin_k: float = 0.0
    # a controller's yaw-rate feed-forward (the NURBS tracker's curvature term, the reference
    # yaw rate of backstepping) read vehicle.yaw_tau_s ahead at the vehicle's speed: the
    # plant's yaw rate lags its command by that time constant, so a feed-forward read where
    # the vehicle is asks for each turn late and the vehicle swings wide of it. On in
    # configs/fleet4.toml; off by default, where with single commands a planner outage ended
    # in contact more often with it (docs/notes/0020-parked-vehicles-and-yaw-lag-lead.md).
    # The immune fuzzy PID has no feed-forward to lead.
    yaw_lag_lead: bool = False
    sequence: SequenceConfig = field(default_factory=SequenceConfig)  # shared by every controller
    speed: SpeedConfig = field(default_factory=SpeedConfig)  # shared by every controller
    nurbs: NurbsGains = field(default_factory=NurbsGains)
    backstepping: BacksteppingGains = field(default_factory=BacksteppingGains)
    fuzzy_pid: FuzzyPidGains = field(default_factory=FuzzyPidGains)

    REMOVED_KEYS: ClassVar[Mapping[str, str]] = {
        "compensate_baselines": "delay compensation is the same for every controller now: "
        "use delay_compensation (on or off for all three)",
    }

    def __post_init__(self) -> None:
        nonneg("jitter_margin_k", self.jitter_margin_k)
        if self.placement not in ("planner", "onboard"):
            raise ConfigValueError(
                "placement", f"{self.placement!r} is unknown, expected 'planner' or 'onboard'"
            )
        if self.kind not in ("nurbs", "backstepping", "fuzzy_pid"):
            raise ConfigValueError(
                "kind", f"{self.kind!r} is unknown, expected 'nurbs', 'backstepping' or 'fuzzy_pid'"
            )
