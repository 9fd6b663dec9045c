"""A paper-like field (section 4: 100 m x 40 m, static and moving obstacles) for tests, benches."""

from __future__ import annotations

from services.planner.geometry import Area, Circle, MovingCircle, Obstacles, Polygon, Pose2D


def paper_area() -> Area:
    return Area(x_min=0.0, x_max=100.0, y_min=0.0, y_max=40.0)


def paper_obstacles() -> Obstacles:
    """Six static circles, two static polygons and two moving circles."""
    circles = (
        Circle(x=18.0, y=17.0, radius=3.0),
        Circle(x=31.0, y=29.0, radius=4.0),
        Circle(x=44.0, y=12.0, radius=3.5),
        Circle(x=57.0, y=25.0, radius=3.0),
        Circle(x=73.0, y=16.0, radius=4.0),
        Circle(x=86.0, y=27.0, radius=2.5),
    )
    polygons = (
        Polygon(vertices=((36.0, 19.0), (41.0, 19.0), (41.0, 24.0), (36.0, 24.0))),
        Polygon(vertices=((62.0, 3.0), (69.0, 4.0), (65.0, 10.0))),
    )
    moving = (
        MovingCircle(id=1, x=50.0, y=36.0, vx=0.0, vy=-0.4, radius=1.5),
        MovingCircle(id=2, x=82.0, y=6.0, vx=-0.3, vy=0.3, ax=0.0, ay=0.01, radius=1.5),
    )
    return Obstacles(circles=circles, polygons=polygons, moving=moving)


def paper_start() -> Pose2D:
    return Pose2D(x=5.0, y=20.0, theta=0.0)


def paper_goal() -> Pose2D:
    return Pose2D(x=95.0, y=20.0, theta=0.0)
