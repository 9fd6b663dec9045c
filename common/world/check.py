"""Geometric checks of a loaded scenario's world: simple polygons, start and goal hulls free."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from common.config.budget import DEFAULT_BUDGET, Budget, check_budget
from common.config.errors import ConfigError
from common.config.placement import PlacementConfig
from common.config.world import GoalConfig, PoseConfig, WorldConfig
from common.world.geometry import polygon_area, polygon_is_simple, vertices_array
from common.world.model import World

if TYPE_CHECKING:
    from common.config.scenario import Scenario


def check_scenario(scenario: Scenario, file: str = "", budget: Budget = DEFAULT_BUDGET) -> None:
    """The check `load_scenario(..., check=check_scenario)` runs after loading a scenario."""
    check_world(
        scenario.world,
        file,
        vehicle_radius_m=scenario.vehicle.radius_m,
        rho0_m=scenario.planner.rho0_m,
    )
    check_stations(scenario.placement, scenario.world, file)
    check_fleet(scenario, file)
    check_budget(scenario, file, budget)  # the run's memory and time (common/config/budget.py)


def check_fleet(scenario: Scenario, file: str = "") -> None:
    """Each vehicle of a fleet: its start and goal free of obstacles as world.start/goal are
    (ConfigError at vehicles[i].start/goal), no two hulls touching at their starts or goals
    (they would begin or end the mission in contact), and the placement left at its default
    (per-vehicle placement is not supported yet)."""
    if not scenario.vehicles:
        return
    if scenario.placement.stations or scenario.placement.services:
        raise ConfigError(
            file,
            ("placement",),
            "a fleet ([[vehicles]]) runs every service on its own vehicle's node: "
            "[placement] stations and services are not supported with [[vehicles]] yet",
        )
    for i, (_, m) in enumerate(scenario.members):
        try:
            check_world(m.world, file, vehicle_radius_m=m.vehicle.radius_m, rho0_m=m.planner.rho0_m)
        except ConfigError as exc:
            key = exc.key_path[1:] if exc.key_path[:1] == ("world",) else exc.key_path
            raise ConfigError(file, ("vehicles", i, *key), exc.problem) from None
    for end in ("start", "goal"):
        for i, a in enumerate(scenario.vehicles):
            for j in range(i):
                b = scenario.vehicles[j]
                pa, pb = getattr(a, end), getattr(b, end)
                gap = math.hypot(pa.x_m - pb.x_m, pa.y_m - pb.y_m) - (
                    a.vehicle.radius_m + b.vehicle.radius_m
                )
                if gap <= 0.0:
                    raise ConfigError(
                        file,
                        ("vehicles", i, end),
                        f"{a.id!r} and {b.id!r} touch at their {end}s (hull to hull "
                        f"{gap:.2f} m), expected apart",
                    )


def check_stations(placement: PlacementConfig, cfg: WorldConfig, file: str = "") -> None:
    """Raise ConfigError at `placement.stations[i]` for a station out of the water: beyond
    placement.water_margin_m around the area, or inside a static obstacle (rock or land)."""
    a, margin = cfg.area, placement.water_margin_m
    world = World(cfg) if placement.stations else None
    for i, st in enumerate(placement.stations):
        where = ("placement", "stations", i)
        outside = max(
            a.x_min_m - st.x_m, st.x_m - a.x_max_m, a.y_min_m - st.y_m, st.y_m - a.y_max_m
        )
        if outside > margin:
            raise ConfigError(
                file,
                where,
                f"{st.name!r} at ({st.x_m}, {st.y_m}) lies {outside:.0f} m beyond world.area, "
                f"outside the water (placement.water_margin_m = {margin:g} m)",
            )
        assert world is not None
        oid, d = world.nearest(st.x_m, st.y_m, 0.0, 0.0, moving=False)
        if d <= 0.0:
            raise ConfigError(
                file,
                where,
                f"{st.name!r} at ({st.x_m}, {st.y_m}) lies inside obstacle {oid}, expected "
                "a station in open water",
            )


def check_world(
    cfg: WorldConfig, file: str = "", *, vehicle_radius_m: float = 0.0, rho0_m: float = 0.0
) -> None:
    """Raise ConfigError at key `world...` of `file` for a world whose geometry is unusable.

    The config dataclasses check each value on its own; this needs the geometry model:
    every polygon must be simple with non-zero area; at t = 0 neither the start nor the goal
    may put the hull (a disc of `vehicle_radius_m`) in contact with an obstacle; and the goal
    must keep `rho0_m` from every static one, or the planner could never end a path there.
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
        _check_free(world, file, name, pose, vehicle_radius_m)
    _check_goal_margin(world, file, cfg.goal, vehicle_radius_m, rho0_m)


def _check_free(
    world: World, file: str, name: str, pose: PoseConfig | GoalConfig, r: float
) -> None:
    # eq. (12) with the hull radius r and the obstacles at t = 0: a pose in contact would
    # start (or end) the mission touching an obstacle
    oid, d = world.nearest(pose.x_m, pose.y_m, r, 0.0)
    if d <= 0.0:
        raise ConfigError(
            file,
            ("world", name),
            f"({pose.x_m}, {pose.y_m}) puts the hull (radius {r:g} m, vehicle.radius_m) in "
            f"contact with obstacle {oid} at t = 0: clearance {d:.2f} m, expected > 0 "
            f"(eq. (12))",
        )


def _check_goal_margin(world: World, file: str, pose: GoalConfig, r: float, rho0: float) -> None:
    # eq. (12)-(13): every planned path keeps rho0 from static obstacles, so the planner
    # refuses a goal closer than that (NO_PATH for the whole run); moving ones pass by
    oid, d = world.nearest(pose.x_m, pose.y_m, r, 0.0, moving=False)
    if d < rho0:
        raise ConfigError(
            file,
            ("world", "goal"),
            f"({pose.x_m}, {pose.y_m}) is {d:.2f} m (hull to surface) from obstacle {oid}, "
            f"inside the safe distance planner.rho0_m = {rho0:g} m: no path may end there "
            f"(eq. (12)-(13))",
        )
