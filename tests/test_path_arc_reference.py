"""PathArcReference (on s) agrees with exact NURBS evaluation closely enough to steer by."""

from __future__ import annotations

import math

import numpy as np

from services.planner.geometry.nurbs_curve import NurbsCurve, clamped_uniform_knots
from services.planner.geometry.planned_path import PlannedPath
from services.planner.shaping.path_arc_reference import PathArcReference


def _path() -> PlannedPath:
    ctrl = np.array([[0, 0], [10, 0], [20, 8], [30, 8], [40, -4], [50, 0], [60, 0]], float)
    curve = NurbsCurve(3, ctrl, np.ones(len(ctrl)), clamped_uniform_knots(len(ctrl), 3))
    return PlannedPath(curve)


def test_point_heading_curvature_match_exact_evaluation() -> None:
    path = _path()
    ref = PathArcReference(path, 1.5)
    s = np.linspace(0.0, ref.length, 157)
    u = path.u_at_s(s)
    xy = path.point_at_u(u)
    for i, si in enumerate(s):
        px, py = ref.point_at_s(float(si))
        assert math.hypot(px - xy[i, 0], py - xy[i, 1]) < 1e-4  # m
        dh = math.remainder(
            ref.heading_at_s(float(si)) - float(path.heading_at_u(u[i : i + 1])[0]), 2 * math.pi
        )
        assert abs(dh) < 1e-3  # rad
        assert (
            abs(ref.curvature_at_s(float(si)) - float(path.signed_curvature_at_u(u[i : i + 1])[0]))
            < 1e-3
        )


def test_projection_matches_the_exact_closest_point() -> None:
    path = _path()
    ref = PathArcReference(path, 1.5)
    rng = np.random.default_rng(3)
    for _ in range(200):
        s_true = float(rng.uniform(1.0, ref.length - 1.0))
        u = path.u_at_s(np.array([s_true]))
        p = path.point_at_u(u)[0]
        h = float(path.heading_at_u(u)[0])
        off = float(rng.uniform(-1.5, 1.5))  # a point off the path, along the normal
        q = p + off * np.array([-math.sin(h), math.cos(h)])
        u_exact, _ = path.closest_u(q)
        s_exact = float(path.s_at_u(np.array([u_exact]))[0])
        assert abs(ref.closest_s(float(q[0]), float(q[1]), s_true) - s_exact) < 5e-3  # m
        assert abs(ref.closest_s(float(q[0]), float(q[1]), None) - s_exact) < 5e-3


def test_the_curvature_bound_holds_over_every_stretch_and_leaves_the_speed_unchanged() -> None:
    from common.config.controller import SpeedConfig
    from common.config.vehicle import VehicleConfig
    from services.control.controllers.base import Limits
    from services.control.controllers.speed import target_speed

    ref = PathArcReference(_path(), 1.5)
    rng = np.random.default_rng(5)
    limits = Limits.from_vehicle(VehicleConfig())
    gentle, tight_budget = SpeedConfig(), SpeedConfig(curvature_budget=0.05)

    class Sampled:  # the same path without the bound: every preview sample taken
        length, v_ref = ref.length, ref.v_ref
        curvature_at_s = ref.curvature_at_s

    tight = 0
    for _ in range(300):
        s0 = float(rng.uniform(-1.0, ref.length + 1.0))
        s1 = s0 + float(rng.choice([0.0, 0.01, 0.5, 4.5, 30.0]))
        bound = ref.curvature_bound(s0, s1)
        worst = max(abs(ref.curvature_at_s(float(s))) for s in np.linspace(s0, s1, 41))
        assert worst <= bound <= worst + 0.05, (s0, s1)
        assert bound <= ref.curvature_max  # the whole path's bound holds over every stretch
        for cfg in (gentle, tight_budget):
            v = target_speed(ref, s0, cfg, limits)
            assert v == target_speed(Sampled(), s0, cfg, limits)  # type: ignore[arg-type]
            tight += v < min(ref.v_ref, limits.v_max) and ref.length - s0 > 10.0
    assert tight > 0  # the bends do slow the profile somewhere: both branches were compared
    # the gentle budget leaves v_curv above the cruise speed on the whole path (no stretch's
    # bound asked), the tight one does not (a bound asked at every s)
    w_path = ref.curvature_max * min(ref.v_ref, limits.v_max)  # its fastest turn at cruise
    w_max = min(limits.w_max, -limits.w_min)
    assert w_path <= gentle.curvature_budget * w_max
    assert w_path > tight_budget.curvature_budget * w_max


def test_a_stop_short_of_the_end_brakes_the_speed_profile_there() -> None:
    from common.config.controller import SpeedConfig
    from common.config.vehicle import VehicleConfig
    from services.control.controllers.base import Limits
    from services.control.controllers.speed import target_speed

    ref = PathArcReference(_path(), 1.5)
    cfg, limits = SpeedConfig(), Limits.from_vehicle(VehicleConfig())
    before = [target_speed(ref, s, cfg, limits) for s in (5.0, 27.0)]
    assert ref.stop_s == ref.length
    ref.stop_at(30.0)
    ref.stop_at(45.0)  # a later stop never lifts an earlier one
    assert ref.stop_s == 30.0
    assert target_speed(ref, 30.0, cfg, limits) == max(limits.v_min, 0.0)
    assert target_speed(ref, 35.0, cfg, limits) == max(limits.v_min, 0.0)  # overshot: stays 0
    # v <= sqrt(2 decel d) to the stop, and never above the profile without it
    for s, v0 in zip((5.0, 27.0), before, strict=True):
        v = target_speed(ref, s, cfg, limits)
        assert v <= min(v0, math.sqrt(2.0 * cfg.decel_mps2 * (30.0 - s))) + 1e-12
    assert target_speed(ref, 27.0, cfg, limits) < before[1]  # 3 m from the stop: braking
