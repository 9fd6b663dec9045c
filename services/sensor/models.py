"""Pure measurement models: the navigation fix and one obstacle scan, from given noise draws."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import NDArray

from common.config.sensor import SensorConfig
from common.messages import Detection, NavFix, ObstacleDetections, TruthState
from common.scalar import wrap_angle
from common.world import ObstacleState

FloatArray = NDArray[np.float64]

NAV_DRAWS = 4  # standard normals per fix: x, y, heading, speed
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


def in_view(o: ObstacleState, x: float, y: float, heading: float, cfg: SensorConfig) -> bool:
    """Is the obstacle in the sonar's sector?

    Range is measured to its surface (centre distance - radius <= det_range_m); the bearing
    to its centre must lie within +-det_fov_half_angle_rad of the heading.
    """
    dx, dy = o.x - x, o.y - y
    if math.hypot(dx, dy) - o.radius > cfg.det_range_m:
        return False
    return abs(wrap_angle(math.atan2(dy, dx) - heading)) <= cfg.det_fov_half_angle_rad


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
