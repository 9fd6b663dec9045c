"""The full replan pipeline: safety, curvature, optimality and NO_PATH behaviour."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers.planner_world import (
    circle,
    default_obstacles,
    default_scenario,
    default_start_goal,
    moving_circle,
    polygon,
)
from matplotlib.path import Path as MplPath

from common.config.planner import PlannerConfig
from common.world.geometry import vertices_array
from services.planner.geometry.clearance import StaticField
from services.planner.geometry.nurbs_curve import curvature
from services.planner.geometry.planned_path import PlannedPath
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D, plan_path
from services.planner.search.costmap import build_costmap
from services.planner.search.graph import shortest_path
from services.planner.search.prediction import predicted_discs

CFG = PlannerConfig()
SCENARIO = default_scenario()
START, GOAL = default_start_goal()
N_DENSE = 5000  # independent dense check, finer than the planner's own 2000 samples


def _seg_dist(p: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    ab = b - a
    t = np.clip(((p - a) @ ab) / (ab @ ab), 0.0, 1.0)
    return np.hypot(*(p - (a + t[:, None] * ab)).T)


def _verify(req: PlanRequest, res: PlanResult) -> dict[str, float]:
    """Independent dense verification of an OK plan (matplotlib point-in-polygon, brute force)."""
    assert res.ok, res.reason
    curve = res.curve()
    u = np.linspace(curve.u_min, curve.u_max, N_DENSE)
    pts, d1, d2 = curve.evaluate(u, 2)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    r, rho0 = req.vehicle_radius_m, CFG.rho0_m
    need = rho0 + r  # centre to obstacle surface: rho0 + r (+ r_k for circles, below)
    worst = math.inf
    for circ in req.obstacles.circles:  # eq. (12): |x - c| >= rho0 + r + r_k
        gap = np.hypot(pts[:, 0] - circ.x_m, pts[:, 1] - circ.y_m) - circ.radius_m
        worst = min(worst, float(gap.min()))
    for poly in req.obstacles.polygons:
        v = vertices_array(poly.vertices_m)
        assert not MplPath(v).contains_points(pts).any(), "curve enters a polygon"
        for a, b in zip(v, np.roll(v, -1, axis=0), strict=True):
            worst = min(worst, float(_seg_dist(pts, a, b).min()))
    assert worst >= need - 1e-9, f"static clearance {worst - r:.3f} m < rho0"
    t = s / req.v_ref_mps  # eq. (13): obstacle where it is when the vehicle passes
    worst_m = math.inf
    for o in req.obstacles.moving:
        c = o.centre_at(t, CFG.accel_horizon_s)
        worst_m = min(worst_m, float(np.min(np.hypot(*(pts - c).T))) - o.radius)
    assert worst_m >= need - 1e-9, f"moving clearance {worst_m - r:.3f} m < rho0"
    k = curvature(d1, d2)
    assert k.max() < 1.0 / req.r_min_m, f"curvature {k.max():.4f} >= 1/R_min"  # eq. (20)
    a = req.area
    assert np.all((pts[:, 0] >= a.x_min_m + r) & (pts[:, 0] <= a.x_max_m - r))
    assert np.all((pts[:, 1] >= a.y_min_m + r) & (pts[:, 1] <= a.y_max_m - r))
    # eq. (10): start/goal position and heading
    assert np.allclose(pts[0], [req.start.x, req.start.y], atol=1e-9)
    assert np.allclose(pts[-1], [req.goal.x, req.goal.y], atol=1e-9)
    h0, hf = math.atan2(d1[0, 1], d1[0, 0]), math.atan2(d1[-1, 1], d1[-1, 0])
    assert abs(math.remainder(h0 - req.start.theta, math.tau)) < 1e-9
    if req.fix_goal_heading:
        assert abs(math.remainder(hf - req.goal.theta, math.tau)) < 1e-9
    return {"static": worst - r, "moving": worst_m - r, "k_max": float(k.max()), "length": s[-1]}


def _optimal_grid_length(req: PlanRequest) -> float:
    """Reference: shortest 16-connected path on the SAME occupancy grid (static obstacles and
    predicted moving discs inflated by r + rho0) with ZERO potential cost, its length being
    the sum of its Euclidean segment lengths (eq. (18)), from the exact start to the exact goal.
    """
    static = StaticField.build(req.obstacles.circles, req.obstacles.polygons)
    discs = predicted_discs(req.obstacles.moving, req.start, req.v_ref_mps, 1e3, CFG)
    cmap = build_costmap(req.area, static, discs, req.vehicle_radius_m, CFG)
    cmap = dataclasses.replace(cmap, cost=np.zeros_like(cmap.cost))
    sx, sy = cmap.cell_of(req.start.x, req.start.y)
    gx, gy = cmap.cell_of(req.goal.x, req.goal.y)
    path = shortest_path(cmap, sy * cmap.nx + sx, gy * cmap.nx + gx, 16)
    assert path is not None
    xy = cmap.centre(path.cells % cmap.nx, path.cells // cmap.nx)
    xy[0], xy[-1] = (req.start.x, req.start.y), (req.goal.x, req.goal.y)
    return float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))


def _paper_request(**kw: object) -> PlanRequest:
    base = {
        "start": START,
        "goal": GOAL,
        "area": SCENARIO.world.area,
        "obstacles": default_obstacles(),
        "vehicle_radius_m": SCENARIO.vehicle.radius_m,
    }
    base.update(kw)
    return PlanRequest(**base)  # type: ignore[arg-type]


def test_obstacle_free_straight_line_has_f_l_one() -> None:
    req = _paper_request(obstacles=Obstacles())
    res = plan_path(req, CFG)
    _verify(req, res)
    assert len(res.grid_path) == 2  # line of sight start -> goal
    assert abs(res.f_l - 1.0) < 1e-9
    assert res.length_m <= 1.05 * _optimal_grid_length(req)


def test_a_free_goal_heading_arrives_along_the_last_leg_a_fixed_one_turns_to_it() -> None:
    # westward in open water to a goal given facing east (theta_f = 0) or without a heading
    west = Pose2D(x=85.0, y=20.0, theta=math.pi)
    goal = Pose2D(x=25.0, y=20.0, theta=0.0)
    free = plan_path(
        _paper_request(obstacles=Obstacles(), start=west, goal=goal, fix_goal_heading=False), CFG
    )
    fixed_req = _paper_request(obstacles=Obstacles(), start=west, goal=goal)
    fixed = plan_path(fixed_req, CFG)
    assert free.ok and abs(free.f_l - 1.0) < 1e-6  # straight on
    end = free.curve().evaluate(np.array([free.curve().u_max]), n_ders=1)[1][0]
    assert abs(math.atan2(end[1], end[0]) - math.pi) < 1e-3
    # eq. (10) held: it loops round to arrive facing east, or finds no curve that does
    if fixed.ok:
        _verify(fixed_req, fixed)
        assert fixed.length_m > free.length_m + math.pi * fixed_req.r_min_m
        end = fixed.curve().evaluate(np.array([fixed.curve().u_max]), n_ders=1)[1][0]
        assert abs(math.atan2(end[1], end[0])) < 1e-3


@pytest.mark.parametrize("x0", [95.0, 96.0, 96.5])
def test_a_turn_beside_the_areas_edge_keeps_the_tracking_margin_from_it(x0: float) -> None:
    # a U-turn a few metres from the east edge, in open water: the curve swings out towards
    # the edge; its hull keeps the clearance margin from it, as from an obstacle (on a path
    # grazing the edge a vehicle's predicted pose left the area: no replan could start there)
    start, goal = Pose2D(x=x0, y=14.0, theta=0.0), Pose2D(x=x0, y=26.0, theta=math.pi)
    req = _paper_request(obstacles=Obstacles(), start=start, goal=goal)
    res = plan_path(req, CFG)
    _verify(req, res)
    curve = res.curve()
    pts = curve.evaluate(np.linspace(curve.u_min, curve.u_max, N_DENSE), 0)[0]
    hull_to_edge = req.area.x_max_m - req.vehicle_radius_m - float(pts[:, 0].max())
    assert hull_to_edge >= CFG.clearance_margin_m - 1e-9


def test_paper_field_plan_is_safe_smooth_and_near_optimal() -> None:
    req = _paper_request()
    res = plan_path(req, CFG)
    v = _verify(req, res)
    # clearance >= rho0 (hull to surface), static and moving; curvature < 1/R_min = 0.5
    assert v["static"] >= CFG.rho0_m - 1e-9 and v["moving"] >= CFG.rho0_m - 1e-9
    assert v["k_max"] < 0.5
    assert abs(res.length_m - v["length"]) < 1e-3 * v["length"]
    l_opt = _optimal_grid_length(req)
    # f_L within 5% of the zero-potential 16-connected optimal grid path
    assert res.length_m <= 1.05 * l_opt, (res.length_m, l_opt)
    d_min = math.hypot(req.goal.x - req.start.x, req.goal.y - req.start.y)
    assert abs(res.f_l - res.length_m / d_min) < 1e-12
    assert math.isfinite(res.turn_penalty)  # eq. (19) finite <=> every r_k > R_min


def test_paper_field_from_varied_starts() -> None:
    rng = np.random.default_rng(7)
    for _ in range(8):
        start = Pose2D(
            x=float(rng.uniform(3.0, 8.0)),
            y=float(rng.uniform(15.0, 25.0)),
            theta=float(rng.uniform(-1.0, 1.0)),
        )
        req = _paper_request(start=start)
        res = plan_path(req, CFG)
        _verify(req, res)
        # eq. (19) f_R in the objective trades a little length for less turning: the worst
        # of these starts is 4.7 % over without it, 5.4 % with it (penalty_turn = 1)
        assert res.length_m <= 1.06 * _optimal_grid_length(req)


def test_random_fields_never_yield_a_colliding_path() -> None:
    # any result is either NO_PATH or passes the independent dense check
    rng = np.random.default_rng(2024)
    n_ok = 0
    for _ in range(12):
        circles = tuple(
            circle(
                x=float(rng.uniform(15, 85)),
                y=float(rng.uniform(3, 37)),
                radius=float(rng.uniform(1, 4)),
            )
            for _ in range(int(rng.integers(4, 12)))
        )
        cx, cy = rng.uniform(20, 80), rng.uniform(8, 32)
        square = polygon(((cx, cy), (cx + 4, cy), (cx + 4, cy + 4), (cx, cy + 4)))
        moving = (
            moving_circle(
                id=1,
                x=float(rng.uniform(30, 70)),
                y=float(rng.uniform(0, 40)),
                vx=float(rng.normal(0, 0.3)),
                vy=float(rng.normal(0, 0.3)),
                radius=1.0,
            ),
        )
        req = _paper_request(
            obstacles=Obstacles(circles=circles, polygons=(square,), moving=moving)
        )
        res = plan_path(req, CFG)
        if res.ok:
            n_ok += 1
            _verify(req, res)
        else:
            assert res.reason
    assert n_ok >= 6  # most random fields are passable


def test_wall_across_the_area_gives_no_path() -> None:
    wall = polygon(((49.0, 0.0), (51.0, 0.0), (51.0, 40.0), (49.0, 40.0)))
    res = plan_path(_paper_request(obstacles=Obstacles(polygons=(wall,))), CFG)
    assert res.status == "NO_PATH"
    assert "unreachable" in res.reason
    assert len(res.control_points) == 0
    with pytest.raises(ValueError):
        res.curve()


def test_goal_enclosed_by_a_ring_gives_no_path() -> None:
    # 12 discs of radius 1 on a 6 m ring around the goal: gaps ~1.1 m < 2 (r + rho0) = 2.2 m
    ring = tuple(
        circle(x=80.0 + 6.0 * math.cos(a), y=20.0 + 6.0 * math.sin(a), radius=1.0)
        for a in np.linspace(0.0, math.tau, 12, endpoint=False)
    )
    goal = Pose2D(x=80.0, y=20.0, theta=0.0)
    res = plan_path(_paper_request(goal=goal, obstacles=Obstacles(circles=ring)), CFG)
    assert res.status == "NO_PATH" and "unreachable" in res.reason


def test_goal_inside_the_safety_distance_gives_no_path() -> None:
    obs = Obstacles(circles=(circle(x=95.0, y=21.5, radius=1.0),))  # 0.5 m from goal centre
    res = plan_path(_paper_request(obstacles=obs), CFG)
    assert res.status == "NO_PATH" and "safety distance" in res.reason


def test_start_inside_the_margin_escapes_then_keeps_clearance() -> None:
    # start 0.6 m (hull) from a disc: inside rho0 = 1 m but not in contact
    r_disc = 2.0 - SCENARIO.vehicle.radius_m - 0.6
    obs = Obstacles(circles=(circle(x=5.0, y=22.0, radius=r_disc),))
    start = Pose2D(x=5.0, y=20.0, theta=0.0)
    req = _paper_request(start=start, obstacles=obs)
    res = plan_path(req, CFG)
    assert res.ok, res.reason
    curve = res.curve()
    pts = curve.evaluate(np.linspace(0.0, 1.0, N_DENSE), 0)[0]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    d = np.hypot(pts[:, 0] - 5.0, pts[:, 1] - 22.0) - r_disc - req.vehicle_radius_m
    assert d.min() > 0.0  # never in contact
    assert d[s >= CFG.escape_len_m].min() >= CFG.rho0_m - 1e-9  # margin restored after escape


def test_plan_is_deterministic() -> None:
    a = plan_path(_paper_request(), CFG)
    b = plan_path(_paper_request(), CFG)
    assert np.array_equal(a.control_points, b.control_points)
    assert np.array_equal(a.knots, b.knots) and np.array_equal(a.grid_path, b.grid_path)


def test_a_plans_path_tabulates_the_checks_samples_float_for_float() -> None:
    # the dense check's evaluation is the path's table (the same parameters): the path is
    # the one built afresh from the curve, every table the same floats
    res = plan_path(_paper_request(), CFG)
    assert res.ok and res._samples
    kept, fresh = res.planned_path(), PlannedPath(res.curve())
    assert kept._table_ders is res._samples[0][1]
    for name in ("u_table", "xy_table", "s_table", "_table_ders"):
        assert np.array_equal(getattr(kept, name), getattr(fresh, name)), name
    # a result with other arrays (a curve made from it) does not take them
    other = dataclasses.replace(res, control_points=res.control_points.copy())
    assert other.planned_path()._table_ders is not res._samples[0][1]


def test_astar_and_lbfgsb_variants_also_plan_safely() -> None:
    req = _paper_request()
    for cfg in (
        PlannerConfig(search="astar"),
        PlannerConfig(refine_method="lbfgsb", refine_max_iter=20),
        PlannerConfig(connectivity=16, nurbs_degree=4),
    ):
        res = plan_path(req, cfg)
        _verify(req, res)
        assert res.length_m <= 1.05 * _optimal_grid_length(req)


def test_outside_area_and_degenerate_requests() -> None:
    # a start outside the area (a vehicle that coasted out of it) is led back in first
    # (recover.py); a goal outside it has no path
    back = plan_path(_paper_request(start=Pose2D(x=-1.0, y=5.0, theta=0.0)), CFG)
    assert back.ok and "start outside the area (hull 1.80 m beyond its edge)" in back.reason
    assert plan_path(_paper_request(goal=Pose2D(x=-1.0, y=5.0, theta=0.0)), CFG).status == (
        "NO_PATH"
    )
    assert plan_path(_paper_request(goal=Pose2D(x=5.0, y=20.0, theta=0.0)), CFG).status == "NO_PATH"
    with pytest.raises(ValueError, match="r_min_m"):
        _paper_request(r_min_m=0.0)


def test_moving_obstacle_met_at_an_unpredicted_time_is_avoided() -> None:
    # the straight-line intercept time of this crossing obstacle misses the time the curve
    # really passes (found by a seeded search; with the default config this case needs the
    # second search attempt, which re-blocks the obstacle around the curve's passing time)
    crossing = moving_circle(
        id=1,
        x=40.19401499086155,
        y=38.0,
        vx=0.18916816871832365,
        vy=-0.5899710797090698,
        radius=1.5,
    )
    obs = Obstacles(circles=default_obstacles().circles[:3], moving=(crossing,))
    req = _paper_request(obstacles=obs)
    res = plan_path(req, CFG)
    v = _verify(req, res)
    assert v["moving"] >= CFG.rho0_m


def test_a_start_beside_a_moving_obstacles_track_is_not_walled_off() -> None:
    # the crossing scenario, 19 s in: the vehicle 3 m west of obstacle 10's track, which
    # crosses southwards ahead of it. Its swept discs (where it may be over +-3 s) enclose
    # the start, and the planner answered NO_PATH ("goal unreachable") and stopped the
    # vehicle; the curve that lets the obstacle pass first keeps rho0 at every time
    crossing = moving_circle(id=10, x=30.0, y=21.4, vx=0.0, vy=-0.5, radius=1.5)
    req = _paper_request(
        start=Pose2D(x=27.3, y=18.2, theta=-0.39),
        obstacles=Obstacles(moving=(crossing,)),
        r_min_m=SCENARIO.vehicle.turn_radius_min_m,
    )
    res = plan_path(req, CFG)
    v = _verify(req, res)  # eq. (12)-(13) at t = s / v_ref, independently
    assert v["moving"] >= CFG.rho0_m
