"""World model: hand-computed clearances (eq. 12), trajectories, validation, the paper field."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest
from helpers.planner_world import default_scenario
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import ndimage

from common.config.world import (
    CircleObstacleConfig,
    MovingObstacleConfig,
    PolygonObstacleConfig,
    PoseConfig,
    WorldConfig,
)
from common.world import World
from common.world.check import check_world
from common.world.geometry import (
    Box,
    nearest_distances,
    polygon_centroid,
    polygon_signed_distance,
    vertices_array,
)


def _world(**kw: object) -> World:
    return World(WorldConfig(**kw))  # type: ignore[arg-type]


SQUARE = PolygonObstacleConfig(id=2, vertices_m=(40.0, 10.0, 44.0, 10.0, 44.0, 14.0, 40.0, 14.0))


def test_circle_clearance_hand_computed() -> None:
    w = _world(circles=(CircleObstacleConfig(id=1, x_m=30.0, y_m=10.0, radius_m=2.0),))
    assert w.clearance(35.0, 10.0, 0.5, 0.0) == pytest.approx(5.0 - 2.5, abs=1e-12)
    assert w.clearance(33.0, 14.0, 0.0, 7.0) == pytest.approx(5.0 - 2.0, abs=1e-12)
    assert w.clearance(30.5, 10.0, 0.5, 0.0) == pytest.approx(-2.0, abs=1e-12)  # collision


def test_polygon_clearance_exact_distance() -> None:
    w = _world(polygons=(SQUARE,))
    assert w.clearance(46.0, 12.0, 0.0, 0.0) == pytest.approx(2.0, abs=1e-12)  # edge
    assert w.clearance(46.0, 17.0, 0.0, 0.0) == pytest.approx(math.sqrt(13.0), abs=1e-12)  # corner
    assert w.clearance(42.0, 12.0, 0.0, 0.0) == pytest.approx(-2.0, abs=1e-12)  # centre, inside
    assert w.clearance(41.0, 12.5, 0.5, 0.0) == pytest.approx(-1.5, abs=1e-12)  # inside, minus r
    assert w.clearance(44.0, 12.0, 0.0, 0.0) == pytest.approx(0.0, abs=1e-12)  # on the boundary
    assert w.clearance(46.0, 12.0, 1.25, 0.0) == pytest.approx(0.75, abs=1e-12)


def test_nearest_names_the_obstacle_that_attains_the_clearance() -> None:
    moving = MovingObstacleConfig(id=9, kind="line", x0_m=50.0, y0_m=12.0, vx_mps=1.0, vy_mps=0.0)
    circle = CircleObstacleConfig(id=1, x_m=30.0, y_m=10.0, radius_m=2.0)
    w = _world(circles=(circle,), polygons=(SQUARE,), moving=(moving,))
    assert w.nearest(35.0, 10.0, 0.5, 0.0) == (1, pytest.approx(2.5, abs=1e-12))
    assert w.nearest(46.0, 12.0, 0.0, 0.0) == (2, pytest.approx(2.0, abs=1e-12))
    # at t = 3 s the moving disc (radius 1) is at (53, 12): 1 m from (55, 12) minus r_k
    assert w.nearest(55.0, 12.0, 0.0, 3.0) == (9, pytest.approx(1.0, abs=1e-12))
    assert w.nearest(55.0, 12.0, 0.0, 3.0, moving=False) == (2, pytest.approx(11.0, abs=1e-12))
    for x, y, r, t in [(35.0, 10.0, 0.5, 0.0), (46.0, 17.0, 0.2, 1.0), (55.0, 12.0, 0.0, 3.0)]:
        assert w.nearest(x, y, r, t)[1] == w.clearance(x, y, r, t)
    assert _world().nearest(1.0, 1.0, 0.5, 0.0) == (None, math.inf)


def test_polygon_sensing_uses_centroid_and_circumradius() -> None:
    w = _world(polygons=(SQUARE,))
    (o,) = w.obstacles_at(3.0)
    assert (o.x, o.y, o.radius, o.moving) == pytest.approx((42.0, 12.0, math.sqrt(8.0), False))
    tri = vertices_array((0.0, 0.0, 6.0, 0.0, 0.0, 3.0))
    assert polygon_centroid(tri) == pytest.approx((2.0, 1.0), abs=1e-12)
    # winding does not matter
    assert polygon_signed_distance(tri[::-1].copy(), np.array(1.0), np.array(1.0)) == (
        pytest.approx(-min(1.0, 1.0, (6.0 - 1.0 - 2.0) / math.sqrt(5.0)))
    )


def test_moving_line_clearance() -> None:
    m = MovingObstacleConfig(id=3, kind="line", radius_m=1.0, x0_m=10, y0_m=30, vx_mps=1.0)
    w = _world(moving=(m,))
    # alpha(3) = (13, 30); eq. (12) from (13, 34) with r = 0.5: 4 - 1.5
    assert w.clearance(13.0, 34.0, 0.5, 3.0) == pytest.approx(2.5, abs=1e-12)
    (o,) = w.obstacles_at(3.0)
    assert (o.x, o.y, o.vx, o.vy, o.ax, o.ay) == pytest.approx((13, 30, 1, 0, 0, 0))
    assert o.moving


def test_sinusoid_trajectory_hand_computed() -> None:
    # p0 = (20, 20), v = (1, 0): normal n = (0, 1); A = 2, f = 0.25 Hz
    m = MovingObstacleConfig(
        id=4, kind="sinusoid", x0_m=20, y0_m=20, vx_mps=1.0, amplitude_m=2.0, frequency_hz=0.25
    )
    (o,) = _world(moving=(m,)).obstacles_at(1.0)
    w = 2.0 * math.pi * 0.25
    assert (o.x, o.y) == pytest.approx((21.0, 22.0), abs=1e-12)
    assert (o.vx, o.vy) == pytest.approx((1.0, 0.0), abs=1e-12)
    assert (o.ax, o.ay) == pytest.approx((0.0, -2.0 * w * w), abs=1e-12)


def test_waypoint_loop_hand_computed() -> None:
    # loop (10,10) -> (14,10) -> (14,13) -> back: legs 4, 3, 5 (length 12), 2 m/s
    m = MovingObstacleConfig(
        id=5, kind="waypoints", x0_m=10, y0_m=10, waypoints_m=(14, 10, 14, 13), speed_mps=2.0
    )
    w = _world(moving=(m,))
    expect = {1.0: (12.0, 10.0), 2.5: (14.0, 11.0), 5.0: (11.6, 11.2), 6.0: (10.0, 10.0)}
    for t, (x, y) in expect.items():
        (o,) = w.obstacles_at(t)
        assert (o.x, o.y) == pytest.approx((x, y), abs=1e-12)
    (o,) = w.obstacles_at(5.0)
    assert (o.vx, o.vy) == pytest.approx((-1.6, -1.2), abs=1e-12)


def test_velocity_and_acceleration_match_finite_differences() -> None:
    w = World(default_scenario().world)
    h = 1e-4
    for t in (0.0, 7.3, 21.0):
        before, now, after = w.obstacles_at(t - h), w.obstacles_at(t), w.obstacles_at(t + h)
        for a, o, b in zip(before, now, after, strict=True):
            assert (b.x - a.x) / (2 * h) == pytest.approx(o.vx, abs=1e-6)
            assert (b.y - a.y) / (2 * h) == pytest.approx(o.vy, abs=1e-6)
            assert (b.vx - a.vx) / (2 * h) == pytest.approx(o.ax, abs=1e-6)
            assert (b.vy - a.vy) / (2 * h) == pytest.approx(o.ay, abs=1e-6)


@settings(max_examples=60, deadline=None)
@given(
    xs=st.lists(st.floats(0.0, 100.0), min_size=1, max_size=20),
    y=st.floats(0.0, 40.0),
    r=st.floats(0.0, 3.0),
    t=st.floats(0.0, 120.0),
)
def test_vectorised_equals_scalar(xs: list[float], y: float, r: float, t: float) -> None:
    w = World(default_scenario().world)
    ys = [y + 0.37 * i for i in range(len(xs))]
    ts = [t + 0.5 * i for i in range(len(xs))]
    many = w.clearance_many(np.array(xs), np.array(ys), r, np.array(ts))
    one = [w.clearance(x, yy, r, tt) for x, yy, tt in zip(xs, ys, ts, strict=True)]
    np.testing.assert_allclose(many, one, rtol=0.0, atol=1e-12)


def test_empty_world_has_infinite_clearance() -> None:
    w = _world()
    assert w.clearance(50.0, 20.0, 1.0, 0.0) == math.inf
    assert np.all(np.isinf(w.clearance_many(np.zeros(3), np.zeros(3), 1.0, 0.0)))


@pytest.mark.parametrize(
    ("kw", "message"),
    [
        ({"circles": (CircleObstacleConfig(id=1, x_m=150, y_m=20, radius_m=1),)}, "circles[0]"),
        (
            {
                "circles": (
                    CircleObstacleConfig(id=1, x_m=50, y_m=20, radius_m=1),
                    CircleObstacleConfig(id=1, x_m=60, y_m=20, radius_m=1),
                )
            },
            "used twice",
        ),
        ({"circles": (CircleObstacleConfig(id=1, x_m=6, y_m=20, radius_m=2),)}, "start"),
        ({"circles": (CircleObstacleConfig(id=1, x_m=95, y_m=21, radius_m=2),)}, "goal"),
        ({"start": PoseConfig(x_m=-1.0, y_m=20.0)}, "start"),
        ({"goal_tolerance_m": 0.0}, "goal_tolerance_m"),
    ],
)
def test_world_validation(kw: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        check_world(WorldConfig(**kw))  # type: ignore[arg-type]


BOW_TIE = (0.0, 0.0, 2.0, 2.0, 2.0, 0.0, 0.0, 2.0)
FLAT = (0.0, 0.0, 1.0, 1.0, 2.0, 2.0)


def test_obstacle_validation() -> None:
    with pytest.raises(ValueError, match="radius_m"):
        CircleObstacleConfig(id=1, x_m=1, y_m=1, radius_m=0.0)
    with pytest.raises(ValueError, match="id"):
        CircleObstacleConfig(id=-1, x_m=1, y_m=1, radius_m=1.0)
    with pytest.raises(ValueError, match="simple"):  # a bow tie
        check_world(WorldConfig(polygons=(PolygonObstacleConfig(id=1, vertices_m=BOW_TIE),)))
    with pytest.raises(ValueError, match="zero area"):
        check_world(WorldConfig(polygons=(PolygonObstacleConfig(id=1, vertices_m=FLAT),)))
    with pytest.raises(ValueError, match="speed_mps"):
        MovingObstacleConfig(id=1, kind="waypoints", x0_m=1, y0_m=1, waypoints_m=(2, 2))
    with pytest.raises(ValueError, match="vx_mps"):
        MovingObstacleConfig(id=1, kind="sinusoid", x0_m=1, y0_m=1, amplitude_m=1)


def _connected(w: World, r: float, t: float) -> bool:
    """Start and goal in one free component of the 0.25 m grid with clearance > r."""
    xs, ys = np.arange(0.0, 100.01, 0.25), np.arange(0.0, 40.01, 0.25)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    labels, _ = ndimage.label(w.clearance_many(gx, gy, r, t) > 0.0)
    s, g = labels[20, 80], labels[380, 80]  # (5, 20) and (95, 20)
    return bool(s > 0 and s == g)


def test_default_field_blocked_line_and_4m_passage() -> None:
    cfg = default_scenario().world
    assert (cfg.area.x_max_m, cfg.area.y_max_m) == (100.0, 40.0)
    assert (cfg.start.x_m, cfg.start.y_m, cfg.goal.x_m, cfg.goal.y_m) == (5, 20, 95, 20)
    assert 6 <= len(cfg.circles) + len(cfg.polygons) <= 8
    assert {m.kind for m in cfg.moving} >= {"line", "sinusoid"}
    w = World(cfg)
    line = w.clearance_many(np.linspace(5.0, 95.0, 2000), 20.0, 0.0, 0.0)
    assert line.min() < 0.0  # the straight line is blocked
    # a vehicle of radius 2 m gets through: a passage >= 4 m wide exists, statically and
    # with the moving obstacles frozen at each sampled time
    static = World(dataclasses.replace(cfg, moving=()))
    assert _connected(static, 2.0, 0.0)
    for t in (0.0, 15.0, 28.0, 40.0, 60.0):
        assert _connected(w, 2.0, t), t


_points = st.lists(
    st.tuples(st.floats(-100, 100), st.floats(-100, 100)), min_size=1, max_size=8
).map(lambda p: np.array(p, dtype=np.float64))


@given(a=_points, b=_points)
def test_the_distance_of_two_boxes_bounds_that_of_any_points_inside_them(
    a: np.ndarray, b: np.ndarray
) -> None:
    d = Box.of(a[:, 0], a[:, 1]).distance(Box.of(b[:, 0], b[:, 1]))
    pairwise = np.hypot(*(a[:, None, :] - b[None, :, :]).transpose(2, 0, 1))
    assert 0.0 <= d <= pairwise.min() + 1e-9
    far = b + np.array([500.0, 0.0])  # boxes apart along x: exactly the gap between them
    gap = far[:, 0].min() - a[:, 0].max()
    assert Box.of(a[:, 0], a[:, 1]).distance(Box.of(far[:, 0], a[:, 1])) == pytest.approx(gap)


def test_nearest_distances_are_every_pairs_minimum_across_blocks() -> None:
    rng = np.random.default_rng(7)
    to = rng.uniform(-50.0, 50.0, (37, 2))
    points = rng.uniform(-60.0, 60.0, (300, 2))  # more than one block of rows
    got = nearest_distances(points, to, block=64)
    want = np.array([min(math.hypot(px - qx, py - qy) for qx, qy in to) for px, py in points])
    np.testing.assert_allclose(got, want, rtol=1e-15, atol=0.0)
    assert nearest_distances(to[:3], to)[0] == 0.0
