"""Estimator configuration: pre-filters (eqs. 2, 3), vehicle EKF/UKF with the current, position
fix gating, obstacle tracks, buffer."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.checks import nonneg, positive
from common.config.errors import ConfigValueError

PrefilterKind = Literal["none", "mean", "lag", "mean+lag"]
VehicleFilterKind = Literal["ekf", "ukf"]


@dataclass(frozen=True, kw_only=True)
class EstimatorConfig:
    """How navigation fixes and obstacle detections are fused, and how often to publish."""

    period_s: float = 0.1  # publish "state" and "tracks" every period
    # paper's smoothing stage on the fixes: eq. (2) mean over mean_window, eq. (3) lag
    prefilter: PrefilterKind = "none"
    mean_window: int = 4  # m of eq. (2), in fixes
    lag_time_constant_s: float = 0.2  # T of eq. (3)
    vehicle_filter: VehicleFilterKind = "ekf"
    # continuous white-noise intensities driving the unicycle's v and w (random walks)
    accel_psd_m2_s3: float = 0.05  # of the surge acceleration
    yaw_accel_psd_rad2_s3: float = 0.01  # of the yaw acceleration
    # the current (world frame) that carries the vehicle is estimated too, as a random walk of
    # this intensity (m^2/s^3: its std grows by sqrt(psd t), 4.5 cm/s in 10 s); more follows
    # an eddy's change faster, and lets the estimate wander more in still water
    current_psd_m2_s3: float = 2e-4
    # white velocity over ground in any direction (m^2/s): what the model still leaves out
    position_psd_m2_s: float = 1e-4
    # the hull's sway through the water, a Gauss-Markov process: a hull slips sideways in a
    # turn (the REMUS 100's drift angle at full rudder is ~3.4 deg: ~0.09 m/s at 1.5 m/s) for
    # about as long as the turn's transient; a DVL sees it
    sway_std_mps: float = 0.1
    sway_tau_s: float = 2.0
    max_predict_dt_s: float = 0.1  # longer predictions are split into equal sub-steps
    init_std_xy_m: float = 0.5  # initial belief around the configured start pose
    init_std_theta_rad: float = 0.1
    init_std_v_mps: float = 0.5
    init_std_w_rps: float = 0.1
    init_std_current_mps: float = 0.3  # per axis: the current is unknown at the start
    # the AHRS's heading bias (sensor.navigation = "dvl_usbl"), estimated from this prior:
    # a compass good to ~0.5 deg after calibration (common/config/sensor.py)
    init_std_heading_bias_rad: float = 0.0087
    # absolute position fixes (USBL/LBL, sensor.navigation = "dvl_usbl") are gated on their
    # innovation: one outside this chi-square (2 dof) probability is taken as an outlier and
    # not fused. Two gated in a row that agree with each other say the filter is the one that
    # is lost: it restarts its position from the fix; so does fix_gate_reset_after gated in a
    # row, a last resort (three outliers in a row, 1 in 8000 at 5 % of outliers, once moved a
    # good filter 6 m off)
    fix_gate_probability: float = 0.999
    fix_gate_reset_after: int = 6
    ukf_alpha: float = 0.3  # Merwe scaled sigma points
    ukf_beta: float = 2.0
    ukf_kappa: float = 0.0
    # obstacle tracks: an IMM per id of a constant-velocity and a constant-acceleration
    # Kalman filter (a single CA filter is either too noisy on steady obstacles or too slow
    # on weaving ones); white-noise intensities of each mode
    track_cv_accel_psd_m2_s3: float = 1e-5  # CV mode: white acceleration
    track_jerk_psd_m2_s5: float = 3e-3  # CA mode: white jerk
    track_cv_sojourn_s: float = 100.0  # mean time an obstacle keeps a steady velocity
    track_ca_sojourn_s: float = 2.0  # mean time a manoeuvre lasts
    track_init_std_v_mps: float = 1.0
    track_init_std_a_mps2: float = 0.5
    track_gate_probability: float = 0.9999  # chi-square (2 dof) Mahalanobis gate
    track_timeout_s: float = 3.0  # a track not updated for this long is dropped ...
    # ... unless its obstacle is predicted outside the sonar's sector (sensor.det_range_m,
    # det_fov_half_angle_rad, from the estimated pose): not seeing it there says nothing of
    # where it is, so it coasts on its prediction up to this long after its last detection
    # (an obstacle that fell behind the vehicle's beam still crosses its way); a detection
    # after track_timeout_s starts it afresh. <= track_timeout_s: dropped like any other
    track_coast_s: float = 10.0
    # out-of-sequence fusion: measurements up to history_s older than the newest are re-fused
    history_s: float = 2.0

    def __post_init__(self) -> None:
        for name in (
            "period_s",
            "lag_time_constant_s",
            "max_predict_dt_s",
            "init_std_xy_m",
            "init_std_theta_rad",
            "init_std_v_mps",
            "init_std_w_rps",
            "init_std_current_mps",
            "init_std_heading_bias_rad",
            "sway_tau_s",
            "ukf_alpha",
            "track_init_std_v_mps",
            "track_init_std_a_mps2",
            "track_timeout_s",
            "track_cv_sojourn_s",
            "track_ca_sojourn_s",
            "history_s",
        ):
            positive(name, getattr(self, name))
        for name in (
            "accel_psd_m2_s3",
            "yaw_accel_psd_rad2_s3",
            "current_psd_m2_s3",
            "position_psd_m2_s",
            "sway_std_mps",
            "track_cv_accel_psd_m2_s3",
            "track_jerk_psd_m2_s5",
            "track_coast_s",
        ):
            nonneg(name, getattr(self, name))
        if self.prefilter not in ("none", "mean", "lag", "mean+lag"):
            raise ConfigValueError(
                "prefilter", f"{self.prefilter!r}, expected 'none', 'mean', 'lag' or 'mean+lag'"
            )
        if self.vehicle_filter not in ("ekf", "ukf"):
            raise ConfigValueError(
                "vehicle_filter", f"{self.vehicle_filter!r}, expected 'ekf' or 'ukf'"
            )
        if not (isinstance(self.mean_window, int) and self.mean_window >= 1):
            raise ConfigValueError("mean_window", f"{self.mean_window!r} must be an integer >= 1")
        if not 0.0 < self.fix_gate_probability < 1.0:
            raise ConfigValueError(
                "fix_gate_probability", f"{self.fix_gate_probability!r}, expected (0, 1)"
            )
        if not (isinstance(self.fix_gate_reset_after, int) and self.fix_gate_reset_after >= 1):
            raise ConfigValueError(
                "fix_gate_reset_after", f"{self.fix_gate_reset_after!r} must be an integer >= 1"
            )
        if not 0.0 < self.track_gate_probability < 1.0:
            raise ConfigValueError(
                "track_gate_probability", f"{self.track_gate_probability!r}, expected (0, 1)"
            )
        for name in ("ukf_beta", "ukf_kappa"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(name, f"{getattr(self, name)!r} must be finite")
        if self.ukf_kappa + 9 <= 0:
            raise ConfigValueError(
                "ukf_kappa", f"{self.ukf_kappa!r} must be > -9 (n + kappa > 0, n = 9 states)"
            )
