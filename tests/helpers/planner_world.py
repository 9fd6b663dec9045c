"""The planner tests' world: the default scenario's field, and obstacles in the world's types."""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

from common.config.scenario import Scenario, load_scenario
from common.config.world import CircleObstacleConfig, PolygonObstacleConfig
from common.world import ObstacleState, World
from services.mission.dataflow import command_loop
from services.planner.core import PlannerCore
from services.planner.result import Obstacles, Pose2D

DEFAULT_SCENARIO = Path(__file__).resolve().parents[2] / "configs" / "default.toml"


def default_scenario() -> Scenario:
    """The default scenario: the one paper-like 100 x 40 m field (paper §4) and its vehicle."""
    return load_scenario(DEFAULT_SCENARIO)[0]


def planner_core(s: Scenario, *, expected_downlink_s: float = 0.0, **kw: Any) -> PlannerCore:
    """A planner core of scenario s, its command loop built as the dataflow builds it (`kw`:
    PlannerCore's keyword arguments)."""
    log = logging.getLogger("tidelink.planner")
    loop = command_loop(s, log, expected_downlink_s=expected_downlink_s)
    return PlannerCore(loop, s.planner, s.vehicle, s.world, **kw)


def default_obstacles(t: float = 0.0) -> Obstacles:
    """The default world's obstacles as the planner sees them, moving ones at time t."""
    w = default_scenario().world
    moving = tuple(o for o in World(w).obstacles_at(t) if o.moving)
    return Obstacles(circles=w.circles, polygons=w.polygons, moving=moving)


def default_start_goal() -> tuple[Pose2D, Pose2D]:
    """The default world's start and goal poses."""
    w = default_scenario().world
    return (
        Pose2D(x=w.start.x_m, y=w.start.y_m, theta=w.start.theta_rad),
        Pose2D(x=w.goal.x_m, y=w.goal.y_m, theta=w.goal.theta_rad),
    )


def circle(*, x: float, y: float, radius: float, id: int = 0) -> CircleObstacleConfig:
    """A static circle (m)."""
    return CircleObstacleConfig(id=id, x_m=x, y_m=y, radius_m=radius)


def polygon(vertices: tuple[tuple[float, float], ...], id: int = 0) -> PolygonObstacleConfig:
    """A static polygon from (x, y) vertices (m)."""
    return PolygonObstacleConfig(id=id, vertices_m=tuple(c for v in vertices for c in v))


def moving_circle(
    *,
    id: int,
    x: float,
    y: float,
    radius: float,
    vx: float = 0.0,
    vy: float = 0.0,
    ax: float = 0.0,
    ay: float = 0.0,
) -> ObstacleState:
    """A tracked moving obstacle at plan time t = 0."""
    return ObstacleState(id=id, x=x, y=y, vx=vx, vy=vy, ax=ax, ay=ay, radius=radius, moving=True)
