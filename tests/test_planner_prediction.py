"""Moving-obstacle prediction for the search grid: intercept times and swept discs."""

from __future__ import annotations

import math

import numpy as np
from helpers.planner_world import moving_circle

from common.config.planner import PlannerConfig
from services.planner.geometry.nurbs_curve import NurbsCurve, clamped_uniform_knots
from services.planner.result import Pose2D
from services.planner.search.prediction import intercept_time, passing_discs, predicted_discs

CFG = PlannerConfig(moving_window_s=3.0)


def test_intercept_time_solves_distance_equals_v_t() -> None:
    start = Pose2D(x=0.0, y=0.0, theta=0.0)
    o = moving_circle(id=1, x=30.0, y=0.0, vx=-0.5, vy=0.0, radius=1.0)  # head-on
    t = intercept_time(o, start, 1.5, 5.0, 1e3)
    assert math.isclose(t, 30.0 / 2.0, rel_tol=1e-3)  # closing speed 1.5 + 0.5 = 2 m/s
    away = moving_circle(id=2, x=30.0, y=0.0, vx=3.0, vy=0.0, radius=1.0)  # faster than us
    assert intercept_time(away, start, 1.5, 5.0, 100.0) <= 100.0


def test_predicted_discs_sweep_the_window_around_the_intercept() -> None:
    start = Pose2D(x=0.0, y=20.0, theta=0.0)
    o = moving_circle(id=1, x=45.0, y=0.0, vx=0.0, vy=1.0, radius=1.0)
    discs = predicted_discs((o,), start, 1.5, 1e3, CFG)
    t_hit = intercept_time(o, start, 1.5, CFG.accel_horizon_s, 1e3)
    ys = discs[:, 1]
    assert math.isclose(ys.min(), t_hit - 3.0, abs_tol=1e-9)  # alpha(t) for t in t_hit +- 3 s
    assert math.isclose(ys.max(), t_hit + 3.0, abs_tol=1e-9)
    assert np.all(np.diff(ys) <= 0.5 + 1e-9)  # discs at most r_k / 2 apart: no gaps
    assert np.all(discs[:, 2] == 1.0) and np.all(discs[:, 0] == 45.0)


def test_passing_discs_follow_the_time_the_curve_passes() -> None:
    # straight curve y = 20 from x = 0 to 90 at 1.5 m/s: at x = 45 at t = 30 s
    ctrl = np.stack([np.linspace(0.0, 90.0, 6), np.full(6, 20.0)], axis=1)
    curve = NurbsCurve(3, ctrl, np.ones(6), clamped_uniform_knots(6, 3))
    o = moving_circle(id=1, x=45.0, y=-10.0, vx=0.0, vy=1.0, radius=1.0)  # at y = 20 at t = 30
    discs = passing_discs(curve, (o,), 1.5, CFG)
    ys = discs[:, 1]
    assert abs(ys.min() - 17.0) < 0.3 and abs(ys.max() - 23.0) < 0.3  # t = 30 +- 3 s
