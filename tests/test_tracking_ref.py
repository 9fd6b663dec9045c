"""The tabulated NURBS reference agrees with exact NURBS evaluation closely enough to steer by."""

from __future__ import annotations

import math

import numpy as np

from services.planner.nurbs import Nurbs, clamped_uniform_knots
from services.planner.nurbs_path import NurbsPath
from services.planner.tracking_ref import NurbsReference


def _path() -> NurbsPath:
    ctrl = np.array([[0, 0], [10, 0], [20, 8], [30, 8], [40, -4], [50, 0], [60, 0]], float)
    curve = Nurbs(3, ctrl, np.ones(len(ctrl)), clamped_uniform_knots(len(ctrl), 3))
    return NurbsPath(curve)


def test_point_heading_curvature_match_exact_evaluation() -> None:
    path = _path()
    ref = NurbsReference(path, 1.5)
    s = np.linspace(0.0, ref.length, 157)
    u = path.u_of_s(s)
    xy = path.point(u)
    for i, si in enumerate(s):
        px, py = ref.point(float(si))
        assert math.hypot(px - xy[i, 0], py - xy[i, 1]) < 1e-4  # m
        dh = math.remainder(
            ref.heading(float(si)) - float(path.heading(u[i : i + 1])[0]), 2 * math.pi
        )
        assert abs(dh) < 1e-3  # rad
        assert abs(ref.curvature(float(si)) - float(path.signed_curvature(u[i : i + 1])[0])) < 1e-3


def test_projection_matches_the_exact_closest_point() -> None:
    path = _path()
    ref = NurbsReference(path, 1.5)
    rng = np.random.default_rng(3)
    for _ in range(200):
        s_true = float(rng.uniform(1.0, ref.length - 1.0))
        u = path.u_of_s(np.array([s_true]))
        p = path.point(u)[0]
        h = float(path.heading(u)[0])
        off = float(rng.uniform(-1.5, 1.5))  # a point off the path, along the normal
        q = p + off * np.array([-math.sin(h), math.cos(h)])
        u_exact, _ = path.project(q)
        s_exact = float(path.s_of_u(np.array([u_exact]))[0])
        assert abs(ref.project(float(q[0]), float(q[1]), s_true) - s_exact) < 5e-3  # m
        assert abs(ref.project(float(q[0]), float(q[1]), None) - s_exact) < 5e-3
