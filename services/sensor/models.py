"""Pure measurement models: the navigation fix and one obstacle scan, from given noise draws."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from common.config.sensor import SensorConfig
from common.messages import (
    Detection,
    NavFix,
    ObstacleDetections,
    Odometry,
    PositionFix,
    TruthState,
)
from common.scalar import wrap_angle
from common.world import ObstacleState

FloatArray = NDArray[np.float64]

NAV_DRAWS = 4  # standard normals per fix: x, y, heading, speed
ODOMETRY_DRAWS = 5  # heading, yaw rate, speed through the water, u and v over ground
FIX_DRAWS = 3  # x, y, and a uniform for an outlier
SCAN_DRAWS = 3  # standard normals per obstacle per scan: x, y, radius (plus one uniform)


def nav_fix(truth: TruthState, cfg: SensorConfig, z: FloatArray) -> NavFix:
    """A fix of `truth` with standard-normal draws z = (x, y, heading, speed), at truth.stamp."""
    return NavFix(
        stamp=truth.stamp,
        x=truth.x + cfg.nav_std_xy_m * float(z[0]),
        y=truth.y + cfg.nav_std_xy_m * float(z[1]),
        heading=wrap_angle(truth.theta + cfg.nav_std_heading_rad * float(z[2])),
        speed=truth.v + cfg.nav_std_speed_mps * float(z[3]),
        std_xy=cfg.nav_std_xy_m,
        std_heading=cfg.nav_std_heading_rad,
        std_speed=cfg.nav_std_speed_mps,
    )


def odometry(
    truth: TruthState, cfg: SensorConfig, bias_rad: float, locked: bool, z: FloatArray
) -> Odometry:
    """AHRS, rpm speed and DVL readings of `truth` with standard-normal draws z = (heading,
    yaw rate, water speed, u, v): the heading off by the AHRS's bias, the DVL's velocity over
    ground in the body frame (meaningless, zeros, without bottom lock)."""
    gx, gy = truth.ground_velocity
    c, s = math.cos(truth.theta), math.sin(truth.theta)
    u, v = (c * gx + s * gy, -s * gx + c * gy) if locked else (0.0, 0.0)
    return Odometry(
        stamp=truth.stamp,
        heading=wrap_angle(truth.theta + bias_rad + cfg.ahrs_std_heading_rad * float(z[0])),
        yaw_rate=truth.w + cfg.ahrs_std_yaw_rate_rps * float(z[1]),
        water_speed=truth.v + cfg.rpm_speed_std_mps * float(z[2]),
        bottom_lock=locked,
        u_ground=u + cfg.dvl_std_mps * float(z[3]) if locked else 0.0,
        v_ground=v + cfg.dvl_std_mps * float(z[4]) if locked else 0.0,
        # the reading's own noise: the bias is constant, and the estimator estimates it
        std_heading=cfg.ahrs_std_heading_rad,
        std_yaw_rate=cfg.ahrs_std_yaw_rate_rps,
        std_water_speed=cfg.rpm_speed_std_mps,
        std_velocity=cfg.dvl_std_mps,
    )


def position_fix(truth: TruthState, cfg: SensorConfig, z: FloatArray) -> PositionFix:
    """A USBL fix of `truth` with draws z = (x, y standard normals, a uniform): an outlier,
    usbl_outlier_std_m off, when the uniform is below usbl_outlier_p. It reports the ordinary
    fix's noise: a USBL does not know which fixes are outliers."""
    std = cfg.usbl_outlier_std_m if float(z[2]) < cfg.usbl_outlier_p else cfg.usbl_std_m
    return PositionFix(
        stamp=truth.stamp,
        x=truth.x + std * float(z[0]),
        y=truth.y + std * float(z[1]),
        std_xy=cfg.usbl_std_m,
    )


def in_view(o: ObstacleState, x: float, y: float, heading: float, cfg: SensorConfig) -> bool:
    """Is the obstacle in the sonar's sector (SensorConfig.sees)?"""
    return cfg.sees(x, y, heading, o.x, o.y, o.radius)


def scan(
    obstacles: Sequence[ObstacleState],
    truth: TruthState,
    cfg: SensorConfig,
    u: FloatArray,
    z: FloatArray,
) -> ObstacleDetections:
    """One scan from `truth`'s pose at truth.stamp; obstacles are the world at that time.

    u[i] (uniform) decides the detection of obstacle i, z[i] (3 standard normals) its noise.
    Draws are consumed for every obstacle whether it is visible or not, so visibility never
    shifts the random stream.
    """
    found: list[Detection] = []
    for i, o in enumerate(obstacles):
        if not in_view(o, truth.x, truth.y, truth.theta, cfg) or u[i] >= cfg.p_detect:
            continue
        found.append(
            Detection(
                id=o.id,
                x=o.x + cfg.det_std_xy_m * float(z[i, 0]),
                y=o.y + cfg.det_std_xy_m * float(z[i, 1]),
                # a radius cannot be negative; clipping only bites at > radius/std sigmas
                radius=max(0.0, o.radius + cfg.det_std_radius_m * float(z[i, 2])),
                std_xy=cfg.det_std_xy_m,
                std_radius=cfg.det_std_radius_m,
            )
        )
    return ObstacleDetections(stamp=truth.stamp, detections=tuple(found))
