"""The pruned nearest distances are every pair's floats bit for bit (random inputs, ties
from integer grids, a path sampled as the mission metrics sample it)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from common.world.geometry import FloatArray, nearest_distances

_coord = st.floats(-500.0, 500.0, allow_nan=False)


def _every_pair(points: FloatArray, to: FloatArray) -> FloatArray:
    """The oracle: sqrt of the least (px - qx)^2 + (py - qy)^2 over every pair, at once."""
    d2 = (points[:, None, 0] - to[:, 0]) ** 2 + (points[:, None, 1] - to[:, 1]) ** 2
    return np.sqrt(d2.min(axis=1))


_grid = st.integers(-40, 40).map(float)  # integer coordinates: many equal distances (ties)


@settings(max_examples=150, deadline=None)
@given(
    to=st.lists(st.tuples(_grid, _grid), min_size=1, max_size=300)
    | st.lists(st.tuples(_coord, _coord), min_size=1, max_size=300),
    points=st.lists(st.tuples(_grid, _grid) | st.tuples(_coord, _coord), min_size=0, max_size=80),
    leaf=st.integers(1, 20),
    block=st.integers(1, 64),
)
def test_pruned_nearest_distances_are_every_pairs_floats(
    to: list[tuple[float, float]], points: list[tuple[float, float]], leaf: int, block: int
) -> None:
    q = np.array(to, dtype=np.float64)
    p = np.array(points, dtype=np.float64).reshape(-1, 2)
    want = _every_pair(p, q)
    assert nearest_distances(p, q, leaf=leaf, block=block).tobytes() == want.tobytes()


def test_pruned_nearest_distances_on_a_path_like_the_metrics() -> None:
    rng = np.random.default_rng(11)
    s = np.linspace(0.0, 1.0, 4000)  # metrics.path_points' sample count
    to = np.column_stack([200.0 * s, 30.0 * np.sin(6.0 * s)])
    u = rng.uniform(0.0, 1.0, 1000)
    pts = np.column_stack([200.0 * u, 30.0 * np.sin(6.0 * u)]) + rng.normal(0.0, 4.0, (1000, 2))
    pts[::100] = to[::400]  # 10 points exactly on samples: distance 0
    want = _every_pair(pts, to)
    assert nearest_distances(pts, to).tobytes() == want.tobytes()
    # non-finite input falls back to every pair, whose NaN and inf it keeps
    pts[0] = (np.nan, 0.0)
    pts[1] = (np.inf, 0.0)
    got = nearest_distances(pts, to)
    assert np.isnan(got[0]) and got[1] == np.inf
