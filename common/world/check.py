"""Geometric checks of a loaded scenario's world: simple polygons, start and goal not inside."""

from __future__ import annotations

from typing import TYPE_CHECKING

from common.config.budget import DEFAULT_BUDGET, Budget, check_budget
from common.config.errors import ConfigError
from common.config.world import PoseConfig, WorldConfig
from common.world.geometry import polygon_area, polygon_is_simple, vertices_array
from common.world.model import World

if TYPE_CHECKING:
    from common.config.scenario import Scenario


def check_scenario(scenario: Scenario, file: str = "", budget: Budget = DEFAULT_BUDGET) -> None:
    """The check `load_scenario(..., check=check_scenario)` runs after loading a scenario."""
    check_world(scenario.world, file)
    check_budget(scenario, file, budget)  # the run's memory and time (common/config/budget.py)


def check_world(cfg: WorldConfig, file: str = "") -> None:
    """Raise ConfigError at key `world...` of `file` for a world whose geometry is unusable.

    The config dataclasses check each value on its own; this needs the geometry model:
    every polygon must be simple with non-zero area, and start and goal must not lie inside
    an obstacle at t = 0.
    """
    for i, p in enumerate(cfg.polygons):
        v = vertices_array(p.vertices_m)
        where = ("world", "polygons", i, "vertices_m")
        if not polygon_is_simple(v):
            raise ConfigError(file, where, "edges cross each other, expected a simple polygon")
        if abs(polygon_area(v)) < 1e-9:
            raise ConfigError(file, where, "the polygon has zero area, expected a proper polygon")
    world = World(cfg)
    for name, pose in (("start", cfg.start), ("goal", cfg.goal)):
        _check_free(world, file, name, pose)


def _check_free(world: World, file: str, name: str, pose: PoseConfig) -> None:
    # eq. (12) with r = 0 and the obstacles at t = 0: the pose must not lie inside any.
    if world.clearance(pose.x_m, pose.y_m, 0.0, 0.0) <= 0.0:
        raise ConfigError(
            file, ("world", name), f"({pose.x_m}, {pose.y_m}) lies inside an obstacle at t = 0"
        )
