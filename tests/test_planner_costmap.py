"""Cost grid: occupancy by inflation, eq. (6) potential, eq. (17) smoothing, exact distances."""

from __future__ import annotations

import math

import numpy as np
from helpers.planner_world import circle, default_obstacles, default_scenario, moving_circle
from matplotlib.path import Path as MplPath

from common.config.planner import PlannerConfig, grid_shape
from common.config.world import AreaConfig, CircleObstacleConfig, PolygonObstacleConfig
from common.world.geometry import vertices_array
from services.planner.geometry.clearance import StaticField
from services.planner.search.costmap import build_costmap, repulsive_cost, smoothing_kernel

R_VEH = default_scenario().vehicle.radius_m
NO_DISCS = np.zeros((0, 3))
AREA = default_scenario().world.area


def _brute_distance(
    pts: np.ndarray,
    circles: tuple[CircleObstacleConfig, ...],
    polys: tuple[PolygonObstacleConfig, ...],
) -> np.ndarray:
    """Signed distance to the nearest obstacle surface, computed the slow independent way."""
    best = np.full(len(pts), np.inf)
    for c in circles:
        best = np.minimum(best, np.hypot(pts[:, 0] - c.x_m, pts[:, 1] - c.y_m) - c.radius_m)
    for p in polys:
        v = vertices_array(p.vertices_m)
        d = np.full(len(pts), np.inf)
        for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
            ab = b - a
            t = np.clip(((pts - a) @ ab) / (ab @ ab), 0.0, 1.0)
            d = np.minimum(d, np.hypot(*(pts - (a + t[:, None] * ab)).T))
        d = np.where(MplPath(v).contains_points(pts), -d, d)
        best = np.minimum(best, d)
    return best


def test_grid_is_200_by_80_at_half_a_metre() -> None:
    assert grid_shape(AreaConfig(), 0.5) == (200, 80)
    assert grid_shape(AreaConfig(x_max_m=10.2, y_max_m=4.0), 0.5) == (21, 8)


def test_static_field_matches_brute_force_distance_and_gradient() -> None:
    obs = default_obstacles()
    field = StaticField.build(obs.circles, obs.polygons)
    rng = np.random.default_rng(5)
    pts = rng.uniform([0.0, 0.0], [100.0, 40.0], (3000, 2))
    d, g = field.distance(pts)
    assert np.allclose(d, _brute_distance(pts, obs.circles, obs.polygons), atol=1e-9)
    # gradient of the distance field by central differences (away from its kinks)
    h = 1e-6
    dx = (field.distance(pts + [h, 0.0])[0] - field.distance(pts - [h, 0.0])[0]) / (2 * h)
    dy = (field.distance(pts + [0.0, h])[0] - field.distance(pts - [0.0, h])[0]) / (2 * h)
    smooth = np.abs(np.hypot(dx, dy) - 1.0) < 1e-4
    assert smooth.mean() > 0.95
    assert np.allclose(g[smooth], np.stack([dx, dy], axis=1)[smooth], atol=1e-4)


def test_occupancy_is_exactly_the_inflated_obstacles() -> None:
    cfg = PlannerConfig()
    obs = default_obstacles()
    cmap = build_costmap(AREA, StaticField.build(obs.circles, obs.polygons), NO_DISCS, R_VEH, cfg)
    iy, ix = np.mgrid[0 : cmap.ny, 0 : cmap.nx]
    centres = cmap.centre(ix.ravel(), iy.ravel())
    d = _brute_distance(centres, obs.circles, obs.polygons).reshape(cmap.ny, cmap.nx)
    # occupied <=> hull closer than rho0: centre-to-surface distance < r + rho0 (bar the cells
    # whose centre is within r of the area's edge: the hull must stay inside the area)
    ring = math.ceil(R_VEH / cfg.resolution_m)
    interior = np.zeros_like(cmap.blocked)
    interior[ring:-ring, ring:-ring] = True
    assert np.array_equal(cmap.blocked[interior], (d < R_VEH + cfg.rho0_m)[interior])
    near = d < R_VEH + cfg.rho_m + 0.5  # inside the window of every obstacle: exact clearance
    assert np.allclose(cmap.static_clearance[near], d[near], atol=1e-9)
    assert np.all(cmap.static_clearance <= d + 1e-9)  # elsewhere a lower bound


def test_repulsive_cost_follows_eq6_without_smoothing() -> None:
    cfg = PlannerConfig(smoothing_len=0, k_r=0.05, rho0_m=1.0, rho_m=4.0, cost_cap=10.0)
    rho = np.array([0.5, 1.0, 1.1, 1.5, 2.0, 3.0, 3.99, 4.0, 4.01, 10.0])
    expect = np.where(
        rho > 4.0, 0.0, np.clip(0.05 * (1.0 / np.maximum(rho - 1.0, 1e-9) ** 2 - 1.0 / 9.0), 0, 10)
    )
    assert np.allclose(repulsive_cost(rho, cfg), expect, atol=1e-12)
    assert repulsive_cost(np.array([1.0 + 1e-6]), cfg)[0] == 10.0  # capped near rho0
    assert abs(repulsive_cost(np.array([4.0]), cfg)[0]) < 1e-12  # continuous at rho_m
    one = circle(x=50.0, y=20.0, radius=2.0)
    cmap = build_costmap(AreaConfig(), StaticField.build((one,), ()), NO_DISCS, R_VEH, cfg)
    rho_grid = cmap.static_clearance - R_VEH
    free = ~cmap.blocked
    assert np.allclose(cmap.cost[free], repulsive_cost(rho_grid, cfg)[free], atol=1e-12)


def test_eq17_kernel_and_smoothing() -> None:
    assert np.allclose(smoothing_kernel(2), np.array([1, 2, 2, 2, 1]) / 8.0)
    assert np.allclose(smoothing_kernel(1), np.array([1, 2, 1]) / 4.0)
    assert np.allclose(smoothing_kernel(0), [1.0])
    cfg = PlannerConfig(smoothing_len=3)
    one = circle(x=50.0, y=20.0, radius=2.0)
    smooth = build_costmap(AreaConfig(), StaticField.build((one,), ()), NO_DISCS, R_VEH, cfg)
    raw = build_costmap(
        AreaConfig(), StaticField.build((one,), ()), NO_DISCS, R_VEH, PlannerConfig(smoothing_len=0)
    )
    free = ~smooth.blocked
    assert np.all(smooth.cost >= 0.0)
    # smoothing spreads the cost: non-zero a little beyond rho_m, lower peak next to the wall
    assert np.count_nonzero(smooth.cost[free]) > np.count_nonzero(raw.cost[free])
    assert smooth.cost[free].max() < raw.cost[free].max()


def test_bilinear_static_clearance_is_within_resolution_sqrt2() -> None:
    obs = default_obstacles()
    field = StaticField.build(obs.circles, obs.polygons)
    cmap = build_costmap(AREA, field, NO_DISCS, R_VEH, PlannerConfig())
    rng = np.random.default_rng(9)
    pts = rng.uniform([0.0, 0.0], [100.0, 40.0], (5000, 2))
    exact = field.distance(pts)[0]
    approx, grad = cmap.static_clearance_at(pts)
    assert np.all(exact >= approx - 0.5 * math.sqrt(2.0) - 1e-9)  # what the final check relies on
    assert np.all(np.hypot(grad[:, 0], grad[:, 1]) <= math.sqrt(2.0) + 1e-9)


def test_moving_discs_block_cells_and_prediction_holds_acceleration_to_the_horizon() -> None:
    o = moving_circle(id=3, x=10.0, y=5.0, vx=1.0, vy=0.0, ax=0.0, ay=0.2, radius=1.0)
    t = np.array([0.0, 2.0, 5.0, 8.0])
    p = o.centre_at(t, accel_horizon_s=5.0)
    assert np.allclose(p[:3, 1], 5.0 + 0.1 * t[:3] ** 2)  # alpha(t) = p + v t + a t^2 / 2
    assert np.isclose(p[3, 1], 5.0 + 0.1 * 25.0 + 1.0 * 3.0)  # then constant velocity a T
    shifted = o.advanced(2.0)
    assert np.allclose(
        shifted.centre_at(np.array([1.0]), math.inf), o.centre_at(np.array([3.0]), math.inf)
    )
    disc = np.array([[30.0, 20.0, 1.0]])  # x, y, radius
    cmap = build_costmap(AreaConfig(), StaticField.build((), ()), disc, R_VEH, PlannerConfig())
    ix, iy = cmap.cell_of(30.0, 20.0)
    assert cmap.blocked[iy, ix] and not cmap.blocked[0 + 10, 0 + 10]
    assert np.all(cmap.static_clearance > 4.0)  # the static grid stays free of moving discs


def test_a_cost_map_on_a_field_used_before_is_the_one_built_afresh() -> None:
    # the static clearance grid is built once per field and grid (StaticField.grids) and the
    # field once per chart: a map built after others, with other discs, is the same floats
    obs = default_obstacles()
    circles, polys = obs.circles, obs.polygons
    discs = np.array([[20.0, 10.0, 2.0], [35.0, 18.0, 1.5]])
    cfg = PlannerConfig()
    field = StaticField.build(circles, polys)
    assert StaticField.build(circles, polys) is field
    first = build_costmap(AREA, field, NO_DISCS, R_VEH, cfg)
    again = build_costmap(AREA, field, discs, R_VEH, cfg)
    StaticField.build.cache_clear()
    afresh = build_costmap(AREA, StaticField.build(circles, polys), discs, R_VEH, cfg)
    assert StaticField.build(circles, polys) is not field
    for name in ("clearance", "static_clearance", "blocked", "cost"):
        assert getattr(again, name).tobytes() == getattr(afresh, name).tobytes(), name
    assert first.static_clearance is again.static_clearance
    assert not again.static_clearance.flags.writeable
