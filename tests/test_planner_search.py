"""Weighted grid graph of eq. (15)-(16): arc weights, Dijkstra vs A*, pruning, walls."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from helpers.planner_world import circle, default_obstacles, default_scenario, polygon

from common.config.planner import PlannerConfig
from common.config.world import AreaConfig
from services.planner.geometry.clearance import StaticField
from services.planner.search.costmap import CostMap, build_costmap
from services.planner.search.graph import directions, edge_weights, shortest_path
from services.planner.search.prune import prune_path, segment_cost

CFG = PlannerConfig()
R_VEH = 0.1  # the hand-built geometries below are sized for this vehicle radius (m)
NO_DISCS = np.zeros((0, 3))  # no predicted moving discs


def _paper_map() -> CostMap:
    obs, s = default_obstacles(), default_scenario()
    static = StaticField.build(obs.circles, obs.polygons)
    return build_costmap(s.world.area, static, NO_DISCS, s.vehicle.radius_m, CFG)


def _idx(cmap: CostMap, x: float, y: float) -> int:
    ix, iy = cmap.cell_of(x, y)
    return iy * cmap.nx + ix


def test_arc_weights_are_length_times_one_plus_mean_cost() -> None:
    cmap = _paper_map()
    for conn in (8, 16):
        w = edge_weights(cmap, conn)
        dirs = directions(conn)
        res = cmap.resolution_m
        iy, ix = 30, 60  # an interior cell; check every direction against the definition
        for k, (dx, dy) in enumerate(dirs):
            if abs(dx) + abs(dy) == 1 or abs(dx) == abs(dy):
                cells = [(0, 0), (dx, dy)]
                walls = cells + ([(dx, 0), (0, dy)] if abs(dx) == abs(dy) else [])
            else:
                sx, sy = int(math.copysign(1, dx)), int(math.copysign(1, dy))
                mid = [(0, sy), (dx, sy)] if abs(dy) == 2 else [(sx, 0), (sx, dy)]
                cells = walls = [(0, 0), *mid, (dx, dy)]
            mean = np.mean([cmap.cost[iy + oy, ix + ox] for ox, oy in cells])
            blocked = any(cmap.blocked[iy + oy, ix + ox] for ox, oy in walls)
            expect = math.inf if blocked else math.hypot(dx, dy) * res * (1.0 + mean)
            assert w[iy, ix, k] == expect or math.isclose(w[iy, ix, k], expect, rel_tol=1e-12)
        # every arc touching an occupied cell is absent
        assert cmap.blocked.any()
        assert np.all(np.isinf(w[cmap.blocked]))


def test_dijkstra_and_astar_agree_on_the_optimal_cost() -> None:
    cmap = _paper_map()
    s, g = _idx(cmap, 5.0, 20.0), _idx(cmap, 95.0, 20.0)
    for conn in (8, 16):
        d = shortest_path(cmap, s, g, conn, "dijkstra")
        a = shortest_path(cmap, s, g, conn, "astar")
        assert d is not None and a is not None
        assert math.isclose(d.g[-1], a.g[-1], rel_tol=1e-12)
        assert d.cells[0] == s and d.cells[-1] == g
        assert np.all(np.diff(d.g) > 0.0)
    c8 = shortest_path(cmap, s, g, 8)
    c16 = shortest_path(cmap, s, g, 16)
    assert c8 is not None and c16 is not None
    assert c16.g[-1] <= c8.g[-1] + 1e-9  # more arcs can only help


def test_free_field_straight_path_prunes_to_two_waypoints() -> None:
    cmap = build_costmap(AreaConfig(), StaticField.build((), ()), NO_DISCS, R_VEH, CFG)
    s, g = _idx(cmap, 5.25, 20.25), _idx(cmap, 95.25, 20.25)
    path = shortest_path(cmap, s, g, 16)
    assert path is not None
    assert math.isclose(path.g[-1], 90.0, rel_tol=1e-12)  # eq. (16): sum of arc lengths
    wp = prune_path(cmap, path, np.array([5.25, 20.25]), np.array([95.25, 20.25]))
    assert wp.shape == (2, 2)


def test_pruned_segments_are_free_and_no_dearer_than_the_grid_path() -> None:
    cmap = _paper_map()
    start, goal = np.array([5.0, 20.0]), np.array([95.0, 20.0])
    path = shortest_path(cmap, _idx(cmap, *start), _idx(cmap, *goal), 8)
    assert path is not None
    wp = prune_path(cmap, path, start, goal)
    assert 2 < len(wp) < len(path.cells) / 4
    costs = [segment_cost(cmap, a, b) for a, b in zip(wp[:-1], wp[1:], strict=True)]
    assert all(math.isfinite(c) for c in costs)
    assert sum(costs) <= 1.01 * path.g[-1] + 1e-9  # Theta*-style acceptance, 1% slack
    # without the potential, the pruned (any-angle) length of eq. (18) is at most the
    # 8-connected grid length, and within 3% of the 16-connected one (or below it)
    zero = dataclasses.replace(cmap, cost=np.zeros_like(cmap.cost))
    g8 = shortest_path(zero, _idx(cmap, *start), _idx(cmap, *goal), 8)
    g16 = shortest_path(zero, _idx(cmap, *start), _idx(cmap, *goal), 16)
    assert g8 is not None and g16 is not None

    def polyline(cells: np.ndarray) -> float:  # grid path from the exact start to the exact goal
        xy = zero.centre(cells % zero.nx, cells // zero.nx)
        xy[0], xy[-1] = start, goal
        return float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))

    wp0 = prune_path(zero, g8, start, goal)
    length = float(np.sum(np.hypot(*np.diff(wp0, axis=0).T)))
    assert length <= polyline(g8.cells) + 1e-9
    assert length <= 1.03 * polyline(g16.cells)  # greedy pruning of an 8-connected path


def test_a_wall_makes_the_goal_unreachable() -> None:
    wall = polygon(((49.0, 0.0), (51.0, 0.0), (51.0, 40.0), (49.0, 40.0)))
    cmap = build_costmap(AreaConfig(), StaticField.build((), (wall,)), NO_DISCS, R_VEH, CFG)
    s, g = _idx(cmap, 5.0, 20.0), _idx(cmap, 95.0, 20.0)
    assert shortest_path(cmap, s, g, 8) is None
    assert shortest_path(cmap, s, g, 16, "astar") is None
    # a gap wider than 2 (r + rho0) = 2.2 m (plus a cell) opens it again
    top = polygon(((49.0, 22.0), (51.0, 22.0), (51.0, 40.0), (49.0, 40.0)))
    low = polygon(((49.0, 0.0), (51.0, 0.0), (51.0, 19.0), (49.0, 19.0)))
    cmap2 = build_costmap(AreaConfig(), StaticField.build((), (top, low)), NO_DISCS, R_VEH, CFG)
    assert shortest_path(cmap2, s, g, 8) is not None


def test_a_thin_diagonal_wall_is_not_leaked_through_a_corner() -> None:
    # a one-cell diagonal staircase of occupied cells: 8-connected arcs may not cut its corners
    cmap = build_costmap(
        AreaConfig(x_max_m=10.0, y_max_m=10.0), StaticField.build((), ()), NO_DISCS, R_VEH, CFG
    )
    blocked = np.zeros_like(cmap.blocked)
    for i in range(cmap.nx):
        blocked[i, i] = True
    cmap = dataclasses.replace(cmap, blocked=blocked, cost=np.zeros_like(cmap.cost))
    s, g = _idx(cmap, 8.0, 1.0), _idx(cmap, 1.0, 8.0)
    assert shortest_path(cmap, s, g, 8) is None and shortest_path(cmap, s, g, 16) is None
    assert shortest_path(cmap, s, _idx(cmap, 9.0, 2.0), 8) is not None


def test_disc_around_the_start_is_searched_out_of() -> None:
    disc = (circle(x=20.0, y=20.0, radius=3.0),)
    cmap = build_costmap(AreaConfig(), StaticField.build(disc, ()), NO_DISCS, R_VEH, CFG)
    assert not cmap.blocked[cmap.cell_of(20.0, 24.5)[1], cmap.cell_of(20.0, 24.5)[0]]
    path = shortest_path(cmap, _idx(cmap, 20.0, 24.5), _idx(cmap, 20.0, 15.5), 8)
    assert path is not None  # around the disc
    assert path.g[-1] > 9.0
