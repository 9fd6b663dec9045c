"""Sensor configuration: navigation fix (USBL/compass/DVL) and obstacle sonar noise and rates."""

from __future__ import annotations

import math
from dataclasses import dataclass

from common.config.checks import nonneg, positive
from common.config.errors import ConfigValueError


@dataclass(frozen=True, kw_only=True)
class SensorConfig:
    """Rates and noise of the navigation fix and of the obstacle scans.

    The core steps at the faster rate; the slower rate must divide it (integer tick counts).
    """

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

    def __post_init__(self) -> None:
        for name in ("nav_rate_hz", "obstacle_rate_hz", "det_range_m"):
            positive(name, getattr(self, name))
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

    @property
    def scan_every(self) -> int:
        """Steps between two obstacle scans: the sonar scans at every multiple of this many
        step periods from its first step (t = 0, or a fleet vehicle's phase)."""
        return round(self.base_rate_hz / self.obstacle_rate_hz)
