"""The world's one-time paths hold the vectorised computation's floats bit for bit: a
trajectory's state, the obstacles at a time, an extrapolated centre, a polygon's distance
without its gradient (random inputs; bits compared, so a -0.0 for a +0.0 fails too)."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from common.config.world import (
    AreaConfig,
    CircleObstacleConfig,
    MovingKind,
    MovingObstacleConfig,
    PolygonObstacleConfig,
    WorldConfig,
)
from common.world import ObstacleState, World
from common.world.geometry import FloatArray, PolygonEdges, polygon_signed_distance
from common.world.trajectory import make_trajectory

_coord = st.floats(-500.0, 500.0, allow_nan=False)
_speed = st.floats(0.05, 3.0).flatmap(lambda s: st.sampled_from([s, -s]))
_time = st.floats(0.0, 2000.0) | st.integers(0, 2000).map(float)
_AREA = AreaConfig(x_min_m=-560.0, x_max_m=560.0, y_min_m=-560.0, y_max_m=560.0)


def _bits(*values: object) -> bytes:
    """The values' float64 bit patterns."""
    return np.asarray(values, dtype=np.float64).tobytes()


@st.composite
def _moving(draw: st.DrawFn) -> MovingObstacleConfig:
    """A moving obstacle of any kind (id 9), inside +-500 m."""
    x0, y0, r = draw(_coord), draw(_coord), draw(st.floats(0.2, 5.0))
    if draw(st.booleans()):
        more = draw(st.lists(st.tuples(_coord, _coord), max_size=4))
        # the first waypoint 10 m from p0: a loop of non-zero length
        pts = (x0 + 10.0, y0, *(c for xy in more for c in xy))
        return MovingObstacleConfig(
            id=9, kind="waypoints", x0_m=x0, y0_m=y0, radius_m=r, waypoints_m=pts, speed_mps=1.5
        )
    kind: MovingKind = draw(st.sampled_from(["line", "sinusoid"]))
    return MovingObstacleConfig(
        id=9,
        kind=kind,
        x0_m=x0,
        y0_m=y0,
        radius_m=r,
        vx_mps=draw(_speed),
        vy_mps=draw(_speed),
        amplitude_m=draw(st.floats(0.0, 20.0)),
        frequency_hz=draw(st.floats(0.001, 0.5)),
        phase_rad=draw(st.floats(-math.pi, math.pi)),
    )


@settings(max_examples=300, deadline=None)
@given(cfg=_moving(), t=_time)
def test_one_times_state_is_the_vectorised_states_floats(
    cfg: MovingObstacleConfig, t: float
) -> None:
    traj = make_trajectory(cfg)
    pos, vel, acc = traj.state(t)
    want = _bits(*pos, *vel, *acc)
    assert _bits(*traj.motion_at(t)) == want
    assert _bits(*traj.position_at(t)) == want[:16]
    # one time inside an array of times: the same floats again
    many = traj.state(np.array([t / 2.0, t]))
    assert _bits(*many[0][1], *many[1][1], *many[2][1]) == want


@settings(max_examples=100, deadline=None)
@given(
    moving=st.lists(_moving(), min_size=0, max_size=3),
    t=_time,
    ids=st.permutations(list(range(1, 6))),
)
def test_obstacles_at_are_the_states_built_from_each_trajectory(
    moving: list[MovingObstacleConfig], t: float, ids: list[int]
) -> None:
    circle = CircleObstacleConfig(id=0, x_m=3.0, y_m=4.0, radius_m=1.5)
    square = PolygonObstacleConfig(
        id=0, vertices_m=(40.0, 10.0, 44.0, 10.0, 44.0, 14.0, 40.0, 14.0)
    )
    order = ids[: 2 + len(moving)]  # ids in no particular order: obstacles_at sorts them
    cfg = WorldConfig(
        area=_AREA,
        circles=(dataclasses.replace(circle, id=order[0]),),
        polygons=(dataclasses.replace(square, id=order[1]),),
        moving=tuple(dataclasses.replace(m, id=i) for m, i in zip(moving, order[2:], strict=True)),
    )
    w = World(cfg)
    # the general construction: each trajectory's vectorised state, made floats
    want_moving = [
        ObstacleState.of_motion(m.id, m.radius_m, *make_trajectory(m).state(t)) for m in cfg.moving
    ]
    assert list(w.moving_at(t)) == want_moving
    got = w.obstacles_at(t)
    assert [o.id for o in got] == sorted(order) == list(w.obstacle_ids)
    assert [o for o in got if o.moving] == sorted(want_moving, key=lambda o: o.id)
    for o in got:
        assert all(type(getattr(o, f)) is float for f in ("x", "y", "vx", "vy", "ax", "ay"))
    # the clearance's moving part: the position the vectorised state gives
    for m in cfg.moving:
        (px, py), _, _ = make_trajectory(m).state(t)
        d = math.hypot(1.0 - float(px), 2.0 - float(py)) - (0.5 + m.radius_m)
        assert w.nearest(1.0, 2.0, 0.5, t)[1] <= d


@settings(max_examples=300, deadline=None)
@given(
    xy=st.tuples(_coord, _coord),
    v=st.tuples(_speed, _speed),
    a=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),
    t=st.floats(-5.0, 120.0) | st.sampled_from([0.0, -0.0, 5.0]),
    horizon=st.sampled_from([math.inf, 0.0, 5.0]) | st.floats(0.0, 60.0),
)
def test_one_times_centre_is_the_vectorised_centre(
    xy: tuple[float, float],
    v: tuple[float, float],
    a: tuple[float, float],
    t: float,
    horizon: float,
) -> None:
    o = ObstacleState.of_motion(3, 1.0, xy, v, a)
    want = o.centre_at(np.array([t]), horizon)[0]
    assert o.centre_at(t, horizon).shape == (2,)
    assert o.centre_at(t, horizon).tobytes() == want.tobytes()
    later = o.advanced(t)
    assert _bits(later.x, later.y) == o.centre_at(np.array([t]))[0].tobytes()


@st.composite
def _star(draw: st.DrawFn) -> FloatArray:
    """A star-shaped polygon (simple): 3 to 9 vertices at increasing angles about a centre."""
    n = draw(st.integers(3, 9))
    cx, cy = draw(_coord), draw(_coord)
    radii = np.array(draw(st.lists(st.floats(0.5, 30.0), min_size=n, max_size=n)))
    ang = 2.0 * np.pi * np.arange(n) / n
    return np.column_stack([cx + radii * np.cos(ang), cy + radii * np.sin(ang)])


@settings(max_examples=150, deadline=None)
@given(
    polys=st.lists(_star(), min_size=1, max_size=3),
    pts=st.lists(st.tuples(_coord, _coord), min_size=1, max_size=20),
    r=st.floats(0.0, 2.0),
)
def test_polygon_distances_without_gradient_are_signed_distances_floats(
    polys: list[FloatArray], pts: list[tuple[float, float]], r: float
) -> None:
    p = np.array(pts)
    many = PolygonEdges.of(polys)
    best, _ = many.signed_distance(p)
    each = many.signed_distances(p)
    assert each[np.arange(len(p)), np.argmin(each, axis=1)].tobytes() == best.tobytes()
    for v in polys:
        alone, _ = PolygonEdges.of([v]).signed_distance(p)
        assert polygon_signed_distance(v, p[:, 0], p[:, 1]).tobytes() == alone.tobytes()
    # the plant's clearance to one polygon: the general signed distance's float, minus r
    w = World(WorldConfig(area=_AREA, polygons=(_polygon_config(polys[0]),)))
    x, y = pts[0]
    want = float(PolygonEdges.of([polys[0]]).signed_distance(p[:1])[0][0]) - r
    got = w.nearest(x, y, r, 0.0)
    assert got[0] == 1 and _bits(got[1]) == _bits(want)


def _polygon_config(v: FloatArray) -> PolygonObstacleConfig:
    """Polygon 1 with vertices v (n, 2)."""
    return PolygonObstacleConfig(id=1, vertices_m=tuple(float(c) for c in v.ravel()))
