"""Sensor configuration: navigation (a fix, or an AUV's DVL + AHRS + USBL) and the obstacle sonar.

Sources of the "dvl_usbl" defaults: a REMUS 100 carries a 1.2 MHz RDI/Teledyne DVL (bottom
track, single-ping noise of ~1 cm/s at survey speed; long-term accuracy +-0.2 % +-1 mm/s, the
datasheet's) and an AHRS/compass good to ~0.5 deg in heading (a fluxgate's deviation after
calibration is of that order: the bias); a ship's USBL fixes it to ~0.2-1 % of slant range
(Kongsberg HiPAP/Sonardyne Ranger datasheets), here 0.5 m at the area's ranges, every few
seconds, and a few per cent of USBL fixes are multipath outliers metres off.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.checks import nonneg, positive
from common.config.errors import ConfigValueError
from common.scalar import wrap_angle


@dataclass(frozen=True, kw_only=True)
class SensorConfig:
    """Rates and noise of the navigation fix and of the obstacle scans.

    The core steps at the faster rate; the slower rate must divide it (integer tick counts).
    """

    # "fix": a navigation fix (position, heading, speed through the water) at nav_rate_hz,
    # Gaussian; "dvl_usbl": an AUV's navigation: AHRS heading and yaw rate and the DVL's
    # velocity over ground at nav_rate_hz (dead reckoning, stream "odometry"), and an absolute
    # USBL fix every usbl_period_min_s..usbl_period_max_s (stream "fix", over its own link)
    navigation: Literal["fix", "dvl_usbl"] = "fix"
    nav_rate_hz: float = 10.0
    obstacle_rate_hz: float = 5.0
    nav_std_xy_m: float = 0.5  # USBL/GPS-like position noise, per axis
    nav_std_heading_rad: float = 0.02  # compass
    nav_std_speed_mps: float = 0.05  # DVL
    det_range_m: float = 30.0  # to the obstacle's surface (centre distance - radius)
    det_fov_half_angle_rad: float = 1.0471975511965976  # 60 deg either side of the heading
    det_std_xy_m: float = 0.2  # sonar/camera position of an obstacle's centre, per axis
    det_std_radius_m: float = 0.1
    p_detect: float = 0.9  # per obstacle per scan
    # -- navigation = "dvl_usbl"
    ahrs_std_heading_rad: float = 0.0087  # 0.5 deg, each reading
    ahrs_bias_std_rad: float = 0.0087  # a constant heading bias drawn once per run
    ahrs_std_yaw_rate_rps: float = 0.005
    # the speed through the water an AUV's navigation takes from its propeller's rpm (a
    # calibrated thrust-speed model: a few cm/s)
    rpm_speed_std_mps: float = 0.05
    dvl_std_mps: float = 0.01  # velocity over ground, per axis, each reading
    # bottom lock is lost at this rate (per s), for dvl_dropout_mean_s on average
    dvl_dropout_per_s: float = 0.02
    dvl_dropout_mean_s: float = 3.0
    usbl_period_min_s: float = 2.0  # the next USBL fix comes this long after the last ...
    usbl_period_max_s: float = 5.0  # ... at most this long (uniform between)
    usbl_std_m: float = 0.5  # per axis
    usbl_outlier_p: float = 0.05  # a fix is an outlier (multipath) with this probability ...
    usbl_outlier_std_m: float = 10.0  # ... and then this far off, per axis

    def __post_init__(self) -> None:
        if self.navigation not in ("fix", "dvl_usbl"):
            raise ConfigValueError(
                "navigation", f"{self.navigation!r}, expected 'fix' or 'dvl_usbl'"
            )
        for name in (
            "nav_rate_hz", "obstacle_rate_hz", "det_range_m", "dvl_dropout_mean_s",
            "usbl_period_min_s",
        ):  # fmt: skip
            positive(name, getattr(self, name))
        for name in (
            "ahrs_std_heading_rad", "ahrs_bias_std_rad", "ahrs_std_yaw_rate_rps", "dvl_std_mps",
            "rpm_speed_std_mps",
            "dvl_dropout_per_s", "usbl_std_m", "usbl_outlier_std_m",
        ):  # fmt: skip
            nonneg(name, getattr(self, name))
        if self.usbl_period_max_s < self.usbl_period_min_s:
            raise ConfigValueError(
                "usbl_period_max_s",
                f"{self.usbl_period_max_s!r} is below usbl_period_min_s "
                f"({self.usbl_period_min_s!r})",
            )
        if not 0.0 <= self.usbl_outlier_p <= 1.0:
            raise ConfigValueError(
                "usbl_outlier_p", f"{self.usbl_outlier_p!r}, expected a probability in [0, 1]"
            )
        for name in (
            "nav_std_xy_m",
            "nav_std_heading_rad",
            "nav_std_speed_mps",
            "det_std_xy_m",
            "det_std_radius_m",
        ):
            nonneg(name, getattr(self, name))
        if not 0.0 < self.det_fov_half_angle_rad <= math.pi:
            raise ConfigValueError(
                "det_fov_half_angle_rad", f"{self.det_fov_half_angle_rad!r}, expected (0, pi]"
            )
        if not 0.0 <= self.p_detect <= 1.0:
            raise ConfigValueError(
                "p_detect", f"{self.p_detect!r}, expected a probability in [0, 1]"
            )
        slow = min(self.nav_rate_hz, self.obstacle_rate_hz)
        ratio = self.base_rate_hz / slow
        if abs(ratio - round(ratio)) > 1e-9 * ratio:
            raise ConfigValueError(
                "obstacle_rate_hz",
                f"{self.base_rate_hz} / {slow} = {ratio:g} Hz ratio, "
                "expected the faster of nav_rate_hz/obstacle_rate_hz to be an integer "
                "multiple of the slower",
            )

    @property
    def base_rate_hz(self) -> float:
        """The core's step rate: the faster of the two streams."""
        return max(self.nav_rate_hz, self.obstacle_rate_hz)

    @property
    def period_s(self) -> float:
        """The core's step period: 1 / base_rate_hz."""
        return 1.0 / self.base_rate_hz

    def sees(
        self,
        x: float,
        y: float,
        heading: float,
        ox: float,
        oy: float,
        radius: float,
        inside_m: float = 0.0,
    ) -> bool:
        """Whether the sonar at (x, y) looking along `heading` (rad) has an obstacle of centre
        (ox, oy) and `radius` (m) in its sector: its surface within det_range_m, the bearing to
        its centre within +-det_fov_half_angle_rad of the heading; with `inside_m`, only when
        the centre may move that far (m) any way and still be so."""
        dx, dy = ox - x, oy - y
        dist = math.hypot(dx, dy)
        if dist - radius + inside_m > self.det_range_m:
            return False
        bearing = abs(wrap_angle(math.atan2(dy, dx) - heading))
        if inside_m > 0.0:
            bearing += math.pi if dist <= inside_m else math.asin(inside_m / dist)
        return bearing <= self.det_fov_half_angle_rad

    @property
    def scan_every(self) -> int:
        """Steps between two obstacle scans: the sonar scans at every multiple of this many
        step periods from its first step (t = 0, or a fleet vehicle's phase)."""
        return round(self.base_rate_hz / self.obstacle_rate_hz)
