"""NurbsCurve (on u) against geomdl and exact circles; PlannedPath's arc length and projection."""

from __future__ import annotations

import math

import numpy as np
from geomdl import NURBS
from hypothesis import given, settings
from hypothesis import strategies as st

from services.planner.geometry.nurbs_curve import (
    NurbsCurve,
    averaged_knots,
    basis_local,
    clamped_uniform_knots,
    curvature,
    rational_basis,
)
from services.planner.geometry.planned_path import PlannedPath


def _random_curve(rng: np.random.Generator) -> NurbsCurve:
    p = int(rng.integers(2, 5))  # degree 2..4
    n = int(rng.integers(p + 1, p + 10))
    ctrl = rng.uniform(-10.0, 10.0, (n, 2))
    w = rng.uniform(0.2, 5.0, n)
    inner = np.sort(rng.uniform(0.0, 1.0, n - p - 1))
    knots = np.concatenate([np.zeros(p + 1), inner, np.ones(p + 1)])
    return NurbsCurve(p, ctrl, w, knots)


def _geomdl(c: NurbsCurve) -> NURBS.Curve:
    g = NURBS.Curve()
    g.degree = c.degree
    g.ctrlptsw = [[x * w, y * w, w] for (x, y), w in zip(c.ctrl, c.weights, strict=True)]
    g.knotvector = c.knots.tolist()
    return g


def test_matches_geomdl_points_and_derivatives_on_random_rational_curves() -> None:
    # 60 random rational curves (degree 2-4, weights in [0.2, 5], clamped random knots);
    # points, C' and C'' agree with geomdl to 1e-9 (relative to max(1, |value|)), at random
    # parameters, the ends, and the interior knots (there only the derivatives that are
    # continuous, orders < degree: one-sided limits of C'' differ at a degree-2 knot)
    rng = np.random.default_rng(20240601)
    worst = 0.0
    for _ in range(60):
        c = _random_curve(rng)
        inner = c.knots[c.degree + 1 : -c.degree - 1]
        u = np.concatenate([rng.uniform(0.0, 1.0, 25), [0.0, 1.0], inner])
        ours = c.evaluate(u, n_ders=2)
        ref_curve = _geomdl(c)
        for j, uj in enumerate(u):
            ref = np.array(ref_curve.derivatives(float(uj), order=2))
            orders = 3 if j < 27 else min(3, c.degree)
            err = np.abs(ref - ours[:, j, :])[:orders] / np.maximum(1.0, np.abs(ref[:orders]))
            worst = max(worst, float(err.max()))
    assert worst < 1e-9


def test_dense_basis_equals_local_basis_and_is_partition_of_unity() -> None:
    rng = np.random.default_rng(3)
    c = _random_curve(rng)
    u = np.linspace(0.0, 1.0, 301)
    r0, r1, r2 = rational_basis(c.knots, c.degree, c.weights, u, 2)
    assert np.allclose(r0.sum(axis=1), 1.0, atol=1e-12)
    assert np.allclose(r1.sum(axis=1), 0.0, atol=1e-9)
    assert np.allclose(r2.sum(axis=1), 0.0, atol=1e-7)
    ev = c.evaluate(u, 2)
    for k, r in enumerate((r0, r1, r2)):
        assert np.allclose(r @ c.ctrl, ev[k], atol=1e-9)


@settings(max_examples=40, deadline=None)
@given(
    degree=st.integers(min_value=2, max_value=5),
    extra=st.integers(min_value=0, max_value=8),
    seed=st.integers(min_value=0, max_value=2**31 - 1),
)
def test_bspline_basis_sums_to_one_and_derivatives_to_zero(
    degree: int, extra: int, seed: int
) -> None:
    rng = np.random.default_rng(seed)
    n = degree + 1 + extra
    knots = averaged_knots(np.cumsum(rng.uniform(0.1, 3.0, (n, 2)), axis=0), degree)
    u = rng.uniform(0.0, 1.0, 50)
    _, ders = basis_local(knots, degree, u, 2)
    assert np.allclose(ders[0].sum(axis=1), 1.0, atol=1e-12)
    assert np.all(ders[0] >= -1e-15)
    assert np.allclose(ders[1].sum(axis=1), 0.0, atol=1e-6 * max(1.0, float(np.abs(ders[1]).max())))


def test_knot_vectors_are_clamped_and_nondecreasing() -> None:
    k = clamped_uniform_knots(7, 3)
    assert np.allclose(k, [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1])
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [5.0, 0.0], [6.0, 1.0], [10.0, 3.0], [11.0, 3.0]])
    a = averaged_knots(pts, 3)
    assert len(a) == len(pts) + 4
    assert np.all(np.diff(a) >= 0.0) and a[0] == 0.0 and a[-1] == 1.0


def _circle_quarter(radius: float) -> NurbsCurve:
    # exact quarter circle: degree 2, weights 1, sqrt(2)/2, 1
    ctrl = np.array([[radius, 0.0], [radius, radius], [0.0, radius]])
    w = np.array([1.0, math.sqrt(0.5), 1.0])
    return NurbsCurve(2, ctrl, w, np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))


def test_rational_quarter_circle_is_exact_radius_and_curvature() -> None:
    radius = 3.0
    c = _circle_quarter(radius)
    u = np.linspace(0.0, 1.0, 500)
    pts, d1, d2 = c.evaluate(u, 2)
    assert np.allclose(np.hypot(pts[:, 0], pts[:, 1]), radius, atol=1e-12)
    assert np.allclose(curvature(d1, d2), 1.0 / radius, atol=1e-9)


def test_arc_length_and_inverse_on_quarter_circle() -> None:
    radius = 3.0
    path = PlannedPath(_circle_quarter(radius), n_table=2000)
    assert abs(path.length - math.pi * radius / 2.0) < 1e-9
    s = np.linspace(0.0, path.length, 37)
    assert np.allclose(path.s_at_u(path.u_at_s(s)), s, atol=1e-9)
    # u(s) puts the point at angle s / R on the circle (table interpolation: < 1 mm)
    p = path.point_at_u(path.u_at_s(s))
    assert np.allclose(np.arctan2(p[:, 1], p[:, 0]), s / radius, atol=1e-3 / radius)


def test_projection_finds_the_closest_point() -> None:
    rng = np.random.default_rng(11)
    for _ in range(10):
        c = _random_curve(rng)
        path = PlannedPath(c, n_table=500)
        dense = c.evaluate(np.linspace(0.0, 1.0, 20001), 0)[0]
        for q in rng.uniform(-10.0, 10.0, (5, 2)):
            u, d = path.closest_u(q)
            brute = float(np.min(np.hypot(*(dense - q).T)))
            # never worse than a 20001-point brute force by more than its own sampling error
            assert d <= brute + 1e-6
            assert abs(d - float(np.hypot(*(path.point_at_u(u)[0] - q)))) < 1e-12


def test_projection_respects_a_parameter_window() -> None:
    path = PlannedPath(_circle_quarter(3.0))
    u, _ = path.closest_u(np.array([3.0, 0.0]), u_lo=0.5, u_hi=1.0)
    assert 0.5 <= u <= 1.0 and abs(u - 0.5) < 1e-9


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 2**32 - 1), n_table=st.integers(2, 3000))
def test_the_table_derivatives_are_those_of_a_lower_order_evaluation(
    seed: int, n_table: int
) -> None:
    # PlannedPath evaluates its table once with two derivatives and answers the points,
    # headings and curvatures on it from that: the floats of evaluating each on its own
    c = _random_curve(np.random.default_rng(seed))
    path = PlannedPath(c, n_table=n_table)
    u = path.u_table.copy()  # not the table itself: evaluated afresh
    for k in (0, 1):
        assert np.array_equal(c.evaluate(u, k), c.evaluate(u, 2)[: k + 1])
    for fn in ("point_at_u", "heading_at_u", "curvature_at_u", "signed_curvature_at_u"):
        table, fresh = getattr(path, fn)(path.u_table), getattr(path, fn)(u)
        assert table.tobytes() == fresh.tobytes(), fn
