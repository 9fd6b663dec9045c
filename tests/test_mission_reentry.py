"""Returns to the optimal path (services/mission/reentry.py) on synthetic distance tracks: none
for a track on the path, exactly k for k excursions, one for chatter at the band's edge."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from services.mission.metrics import ON_PATH_TOL_M
from services.mission.reentry import reentries

TOL = ON_PATH_TOL_M


def _excursions(k: int, depth_m: float = 2.0, n_between: int = 50) -> np.ndarray:
    """A track on the path (d = 0.1 m) that leaves it k times, each a smooth bump to depth_m."""
    bump = depth_m * np.sin(np.linspace(0.0, np.pi, 40))
    parts = [np.full(n_between, 0.1)]
    for _ in range(k):
        parts += [bump, np.full(n_between, 0.1)]
    return np.concatenate(parts)


def test_a_track_on_the_path_never_returns() -> None:
    assert reentries(np.zeros(1000), TOL) == 0
    assert reentries(np.full(1000, 0.9 * TOL), TOL) == 0  # inside the band, off its centre
    assert reentries(np.array([]), TOL) == 0


@given(st.integers(0, 12), st.floats(0.6, 10.0))
def test_k_excursions_are_k_returns(k: int, depth_m: float) -> None:
    assert reentries(_excursions(k, depth_m), TOL) == k


def test_chatter_at_the_edge_of_the_band_counts_once() -> None:
    rng = np.random.default_rng(7)
    # out, then 200 samples jittering +- 0.2 m around the band's edge, then back on the path
    edge = TOL + rng.uniform(-0.2, 0.2, 200)
    d = np.concatenate([np.zeros(50), np.full(20, 1.5), edge, np.zeros(50)])
    assert np.count_nonzero((edge[1:] <= TOL) & (edge[:-1] > TOL)) > 20  # many band crossings
    assert reentries(d, TOL) == 1
    # the same jitter with no clear excursion before it: it left once and came back once
    assert reentries(np.concatenate([np.zeros(50), edge, np.zeros(50)]), TOL) == 1


def test_the_return_is_within_half_the_band() -> None:
    d = np.array([0.0, 1.0, 0.4, 1.0, 0.3, 1.0, 0.2])  # back only once: at 0.2 m <= 0.25 m
    assert reentries(d, TOL) == 1
    assert reentries(np.array([0.0, 1.0, 0.25]), TOL) == 1  # the half-band itself counts


def test_a_start_outside_the_band_is_an_arrival_not_a_return() -> None:
    assert reentries(np.concatenate([np.full(30, 3.0), np.zeros(30)]), TOL) == 0
    assert reentries(np.concatenate([np.full(30, 3.0), _excursions(2)]), TOL) == 2
    # a start in the band's outer half is in the band
    assert reentries(np.concatenate([np.full(30, 0.4), _excursions(2)]), TOL) == 2


@pytest.mark.parametrize("tol", [0.0, -1.0, float("nan"), float("inf")])
def test_a_band_must_have_a_finite_positive_width(tol: float) -> None:
    with pytest.raises(ValueError, match="tol_m"):
        reentries(np.zeros(3), tol)
