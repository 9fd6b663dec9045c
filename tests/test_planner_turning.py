"""Eq. (19) f_R as an arc-length integral: exact on circles, independent of the sample count,
with an exact gradient in the refinement objective, and lowering the planned path's f_R."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from helpers.planner_world import default_obstacles, default_scenario, default_start_goal

from common.config.planner import PlannerConfig
from services.planner.geometry.clearance import StaticField
from services.planner.geometry.nurbs_curve import NurbsCurve, curvature
from services.planner.plan import PlanRequest, fit_problem, plan_path
from services.planner.search.costmap import build_costmap
from services.planner.shaping.fit import FitProblem, initial_curve
from services.planner.shaping.refine import Objective, RefineWeights, gauss_legendre
from services.planner.shaping.turning import K_SMOOTH_PER_M, turn_cost, turn_penalty

SCENARIO = default_scenario()
R_MIN = SCENARIO.vehicle.turn_radius_min_m  # 5 m


def _arc(radius: float) -> NurbsCurve:
    """An exact quarter circle of the given radius (rational: weights 1, sqrt(2)/2, 1)."""
    ctrl = np.array([[radius, 0.0], [radius, radius], [0.0, radius]])
    w = np.array([1.0, math.sqrt(0.5), 1.0])
    return NurbsCurve(2, ctrl, w, np.array([0.0, 0.0, 0.0, 1.0, 1.0, 1.0]))


def _f_r(curve: NurbsCurve, n: int) -> float:
    """F_R by n-point Gauss-Legendre on the curve's (single or many) knot spans."""
    xg, wg = gauss_legendre(n)
    brk = np.unique(curve.knots)
    half = 0.5 * np.diff(brk)
    u = ((0.5 * (brk[:-1] + brk[1:]))[:, None] + half[:, None] * xg[None, :]).ravel()
    _, d1, d2 = curve.evaluate(u, 2)
    ds = (half[:, None] * wg[None, :]).ravel() * np.hypot(d1[:, 0], d1[:, 1])
    return turn_penalty(curvature(d1, d2), ds, R_MIN)


def _length(curve: NurbsCurve) -> float:
    pts = curve.evaluate(np.linspace(curve.u_min, curve.u_max, 20001), 0)[0]
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T)))


def test_on_a_circular_arc_f_r_is_its_length_over_r_minus_r_min() -> None:
    radius = 8.0
    exact = (math.pi * radius / 2.0) / (radius - R_MIN)  # int ds / (r - R_min), r constant
    for n in (6, 12, 20):  # as many samples as you like: the same value
        assert _f_r(_arc(radius), n) == pytest.approx(exact, rel=1e-6)
    # eq. (19)'s second case: a radius below R_min costs infinitely much
    assert _f_r(_arc(4.0), 6) == math.inf


def test_the_finite_extension_beyond_k_b_is_smooth_and_increasing() -> None:
    k_b = 0.85 / R_MIN
    k = np.array([k_b - 1e-7, k_b, k_b + 1e-7, 1.0 / R_MIN, 0.5])
    g, dg = turn_cost(k, R_MIN, k_b)
    assert np.all(np.isfinite(g)) and np.all(np.diff(g) > 0.0) and np.all(dg > 0.0)
    assert g[2] - g[0] == pytest.approx(2e-7 * dg[1], rel=1e-4)  # C1 at k_b
    # below k_b it is eq. (19)'s own 1 / (r - R_min), |k| smoothed within e of 0
    gentle = np.array([0.0, 0.01, 0.1])
    exact, slope = gentle / (1.0 - R_MIN * gentle), 1.0 / (1.0 - R_MIN * gentle) ** 2
    assert np.all(np.abs(turn_cost(gentle, R_MIN, k_b)[0] - exact) <= K_SMOOTH_PER_M * slope)
    assert turn_cost(gentle, R_MIN, k_b)[1][0] == 0.0  # a straight stretch: no kink


def _problem() -> tuple[FitProblem, NurbsCurve, NurbsCurve]:
    """The default field's fit problem, the plan's final curve and its initial fit."""
    cfg = PlannerConfig()
    start, goal = default_start_goal()
    obs = default_obstacles()
    v = SCENARIO.vehicle
    req = PlanRequest(
        start=start,
        goal=goal,
        area=SCENARIO.world.area,
        obstacles=obs,
        vehicle_radius_m=v.radius_m,
        r_min_m=v.turn_radius_min_m,
        v_ref_mps=v.cruise_speed_mps,
    )
    res = plan_path(req, cfg)
    assert res.ok
    static = StaticField.build(obs.circles, obs.polygons)
    grid = build_costmap(req.area, static, np.zeros((0, 3)), v.radius_m, cfg)
    prob = fit_problem(req, cfg, static, grid, start_inside=False)
    first = initial_curve(prob, res.grid_path, cfg.ctrl_spacing_m, cfg.nurbs_degree)
    return prob, res.curve(), first


def test_the_objectives_f_r_does_not_depend_on_the_sample_count() -> None:
    prob, curve, _ = _problem()
    only = RefineWeights(c_d=0.0, c_k=0.0, clear_margin_m=0.0, k_target=0.85 / R_MIN, c_r=1.0)
    f_r = {}
    for per_span in (6, 12):
        with_r = Objective(prob, curve, per_span, only)
        without = Objective(prob, curve, per_span, dataclasses.replace(only, c_r=0.0))
        x = with_r.lay.to_x(curve.ctrl)
        f_r[per_span] = with_r(x)[0] - without(x)[0]
    # twice the samples: the same F_R up to quadrature error (a plain sum would double)
    assert f_r[6] > 1.0 and f_r[12] == pytest.approx(f_r[6], rel=1e-3)
    # eq. (19)'s integral, but for |k| smoothed within e: at most e g'(k_max) per metre
    k_max = float(np.max(curvature(*curve.evaluate(np.linspace(0.0, 1.0, 4000), 2)[1:])))
    slack = K_SMOOTH_PER_M * _length(curve) / (1.0 - R_MIN * k_max) ** 2
    assert abs(f_r[6] - _f_r(curve, 20)) <= slack


def test_the_objective_gradient_with_f_r_matches_finite_differences() -> None:
    prob, _, first = _problem()  # the initial fit: bends near R_min, hinges active
    wts = RefineWeights(c_d=1e3, c_k=3e2, clear_margin_m=0.15, k_target=0.85 / R_MIN, c_r=1.0)
    obj = Objective(prob, first, 6, wts)
    x = obj.lay.to_x(first.ctrl)
    _, g, h = obj(x, hessian=True)
    assert np.all(np.linalg.eigvalsh(h) >= -1e-6 * np.abs(h).max())  # a PSD model
    rng = np.random.default_rng(3)
    for i in rng.choice(len(x), size=12, replace=False):
        e = np.zeros_like(x)
        e[i] = 1e-6
        fd = (obj(x + e)[0] - obj(x - e)[0]) / 2e-6
        assert fd == pytest.approx(g[i], rel=1e-4, abs=1e-4)


def test_f_r_in_the_objective_lowers_the_planned_paths_f_r() -> None:
    start, goal = default_start_goal()
    v = SCENARIO.vehicle
    req = PlanRequest(
        start=start,
        goal=goal,
        area=SCENARIO.world.area,
        obstacles=default_obstacles(),
        vehicle_radius_m=v.radius_m,
        r_min_m=v.turn_radius_min_m,
        v_ref_mps=v.cruise_speed_mps,
    )
    on = plan_path(req, PlannerConfig())
    off = plan_path(req, PlannerConfig(penalty_turn=0.0))
    assert on.ok and off.ok
    assert on.turn_penalty < 0.75 * off.turn_penalty  # measured 5.8 vs 16.6
    assert on.max_curvature < off.max_curvature
    assert on.length_m < 1.01 * off.length_m  # turning less costs (almost) no length
