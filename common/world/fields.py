"""Ready-made obstacle fields; `paper_field` mimics the paper's 100 x 40 m experiment (§4)."""

from __future__ import annotations

from common.config.world import (
    AreaConfig,
    CircleObstacleConfig,
    MovingObstacleConfig,
    PolygonObstacleConfig,
    PoseConfig,
    WorldConfig,
)


def paper_field() -> WorldConfig:
    """A paper-like field: start (5, 20), goal (95, 20), the straight line blocked.

    Seven static obstacles (five circles, two polygons) and two moving ones: a line
    crossing southwards at x = 40 (through y = 20 at t = 28 s) and a sinusoid weaving
    northwards at x ~ 89. The static field leaves passages at least 4 m wide (tested).
    """
    return WorldConfig(
        area=AreaConfig(x_min_m=0.0, x_max_m=100.0, y_min_m=0.0, y_max_m=40.0),
        start=PoseConfig(x_m=5.0, y_m=20.0, theta_rad=0.0),
        goal=PoseConfig(x_m=95.0, y_m=20.0, theta_rad=0.0),
        goal_tolerance_m=1.0,
        circles=(
            CircleObstacleConfig(id=1, x_m=20.0, y_m=20.0, radius_m=4.0),
            CircleObstacleConfig(id=2, x_m=32.0, y_m=8.0, radius_m=4.0),
            CircleObstacleConfig(id=3, x_m=34.0, y_m=32.0, radius_m=4.5),
            CircleObstacleConfig(id=5, x_m=66.0, y_m=9.0, radius_m=4.0),
            CircleObstacleConfig(id=7, x_m=80.0, y_m=21.0, radius_m=3.5),
        ),
        polygons=(
            PolygonObstacleConfig(
                id=4, vertices_m=(46.0, 14.0, 54.0, 14.0, 56.0, 24.0, 48.0, 27.0)
            ),
            PolygonObstacleConfig(id=6, vertices_m=(62.0, 28.0, 72.0, 25.0, 70.0, 36.0)),
        ),
        moving=(
            MovingObstacleConfig(
                id=10, kind="line", radius_m=1.5, x0_m=40.0, y0_m=34.0, vx_mps=0.0, vy_mps=-0.5
            ),
            MovingObstacleConfig(
                id=11,
                kind="sinusoid",
                radius_m=1.5,
                x0_m=89.0,
                y0_m=4.0,
                vx_mps=0.0,
                vy_mps=0.4,
                amplitude_m=3.0,
                frequency_hz=0.05,
                phase_rad=0.0,
            ),
        ),
    )
