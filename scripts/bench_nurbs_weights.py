"""Experiment: should the refinement optimise the NURBS weights too (planner shaping/fit.py)?

Each plan's final curve (plan_path: weights 1) is refined further two ways with the same
iteration budget: (a) the control points only, as the planner does (Levenberg-Marquardt and
L-BFGS-B, the better); (b) control points and weights jointly (w_0 = 1, the others as log w
in [log 0.2, log 5]: the curve is nonlinear in them; L-BFGS-B, their gradient by forward
differences, then LM on the points). Printed per plan: eq. (9)'s F, length, max curvature,
min clearance and F_R (plan / points / joint), whether the dense check passes, CPU time.
Plans: the default field from its start and from varied starts, and random circle fields.
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import minimize

from common.config.planner import PlannerConfig
from common.config.scenario import load_scenario
from common.config.world import CircleObstacleConfig
from common.world.geometry import FloatArray
from services.planner.geometry.clearance import StaticField
from services.planner.geometry.nurbs_curve import NurbsCurve, curvature, rational_basis
from services.planner.plan import Obstacles, PlanRequest, Pose2D, fit_problem, plan_path
from services.planner.search.costmap import build_costmap
from services.planner.shaping.check import check_curve
from services.planner.shaping.refine import (
    Objective,
    RefineWeights,
    gauss_legendre,
    levenberg_marquardt,
    quadrature,
)
from services.planner.shaping.turning import turn_penalty

DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
STEP = 0.05  # L-BFGS-B variable scale (m for points, log units for weights)


def requests(n_varied: int, n_fields: int) -> list[tuple[str, PlanRequest]]:
    """The default field from its start and varied starts; random fields of 4-9 circles."""
    s, _ = load_scenario(DEFAULT_SCENARIO)
    w = s.world
    field = PlanRequest.across(w, s.vehicle).obstacles

    def req(start: Pose2D, obstacles: Obstacles) -> PlanRequest:
        return PlanRequest.across(w, s.vehicle, start=start, obstacles=obstacles)

    start = Pose2D(x=w.start.x_m, y=w.start.y_m, theta=w.start.theta_rad)
    out = [("default", req(start, field))]
    rng = np.random.default_rng(1)
    for i in range(n_varied):
        dx, dy, dth = rng.uniform(-1.0, 1.0), rng.uniform(-2.0, 2.0), rng.uniform(-0.3, 0.3)
        varied = Pose2D(x=start.x + float(dx), y=start.y + float(dy), theta=float(dth))
        out.append((f"varied[{i}]", req(varied, field)))
    rng = np.random.default_rng(2024)
    for i in range(n_fields):
        circles = tuple(
            CircleObstacleConfig(
                id=j + 1,
                x_m=float(rng.uniform(15, 85)),
                y_m=float(rng.uniform(3, 37)),
                radius_m=float(rng.uniform(1, 4)),
            )
            for j in range(int(rng.integers(4, 10)))
        )
        out.append((f"random[{i}]", req(start, Obstacles(circles=circles))))
    return out


def f_r(curve: NurbsCurve, r_min_m: float) -> float:
    """Eq. (19) F_R of a curve, 12 Gauss-Legendre nodes per knot span."""
    xg, wg = gauss_legendre(12)
    brk = np.unique(curve.knots)
    half = 0.5 * np.diff(brk)
    u = ((0.5 * (brk[:-1] + brk[1:]))[:, None] + half[:, None] * xg[None, :]).ravel()
    _, d1, d2 = curve.evaluate(u, 2)
    ds = (half[:, None] * wg[None, :]).ravel() * np.hypot(d1[:, 0], d1[:, 1])
    return turn_penalty(curvature(d1, d2), ds, r_min_m)


class Weighted:
    """F over z = (x, log w_1 .. log w_n-1): the round's objective, its basis rebuilt for w."""

    def __init__(self, obj: Objective, curve: NurbsCurve, per_span: int) -> None:
        self.obj, self.curve = obj, curve
        self.u, _ = quadrature(curve.knots, per_span)
        self.nx = obj.lay.dim

    def weights(self, lw: FloatArray) -> FloatArray:
        w = np.concatenate([[1.0], np.exp(lw)])
        c = self.curve
        self.obj.r0, self.obj.r1, self.obj.r2 = rational_basis(c.knots, c.degree, w, self.u, 2)
        return w

    def __call__(self, z: FloatArray) -> tuple[float, FloatArray]:
        x, lw = z[: self.nx], z[self.nx :]
        self.weights(lw)
        f, gx, _ = self.obj(x)
        gw = np.zeros(len(lw))
        for i in range(len(lw)):  # forward differences: the basis is nonlinear in w
            e = lw.copy()
            e[i] += 1e-6
            self.weights(e)
            gw[i] = (self.obj(x)[0] - f) / 1e-6
        self.weights(lw)
        return f, np.concatenate([gx, gw])


def lbfgsb(
    fun: Callable[[FloatArray], tuple[float, FloatArray]],
    z0: FloatArray,
    lo: FloatArray,
    hi: FloatArray,
    max_iter: int,
) -> FloatArray:
    """L-BFGS-B from z0 in variables scaled by STEP."""

    def scaled(y: FloatArray) -> tuple[float, FloatArray]:
        f, g = fun(z0 + STEP * y)
        return f, STEP * g

    bounds = list(zip(((lo - z0) / STEP).tolist(), ((hi - z0) / STEP).tolist(), strict=True))
    res = minimize(
        scaled, np.zeros_like(z0), jac=True, method="L-BFGS-B", bounds=bounds,
        options={"maxiter": max_iter},
    )  # fmt: skip
    return np.asarray(z0 + STEP * res.x)


@dataclass(frozen=True)
class Variant:
    """One refined curve: eq. (9)'s F, the dense check, length, curvature, clearance, F_R."""

    f: float
    ok: bool
    length_m: float
    k_max: float
    clearance_m: float
    f_r: float


@dataclass(frozen=True)
class Comparison:
    """A plan's curve, refined further on its points only and on points and weights."""

    plan: Variant
    points: Variant
    joint: Variant
    cpu_points_s: float
    cpu_joint_s: float
    w_range: tuple[float, float]


def compare(req: PlanRequest, cfg: PlannerConfig, max_iter: int) -> Comparison | None:
    """Refine one plan's final curve on its points, then on points and weights."""
    res = plan_path(req, cfg)
    if not res.ok:
        return None
    static = StaticField.build(req.obstacles.circles, req.obstacles.polygons)
    grid = build_costmap(req.area, static, np.zeros((0, 3)), req.vehicle_radius_m, cfg)
    prob = fit_problem(req, cfg, static, grid, start_inside=False)
    curve = res.curve()
    wts = RefineWeights.of(cfg, req.r_min_m)
    obj = Objective(prob, curve, cfg.samples_per_span, wts)
    lay = obj.lay
    lo, hi = lay.bounds(prob.area, prob.vehicle_radius_m, 4.0 * prob.r_min_m + 10.0)
    x0 = lay.to_x(curve.ctrl)
    t = time.thread_time()
    xa = levenberg_marquardt(obj, x0, lo, hi, max_iter)
    xb = lbfgsb(lambda x: obj(x)[:2], x0, lo, hi, max_iter)
    xp = xa if obj(xa)[0] <= obj(xb)[0] else xb
    cpu_points = time.thread_time() - t
    wtd = Weighted(obj, curve, cfg.samples_per_span)
    n_w = len(curve.weights) - 1
    big = math.log(5.0)
    t = time.thread_time()
    zj = lbfgsb(
        wtd,
        np.concatenate([x0, np.zeros(n_w)]),
        np.concatenate([lo, np.full(n_w, -big)]),
        np.concatenate([hi, np.full(n_w, big)]),
        max_iter,
    )
    wj = wtd.weights(zj[len(x0) :])
    xj = levenberg_marquardt(obj, zj[: len(x0)], lo, hi, max_iter)
    xj = xj if obj(xj)[0] < obj(zj[: len(x0)])[0] else zj[: len(x0)]
    cpu_joint = time.thread_time() - t

    def variant(x: FloatArray, w: FloatArray) -> Variant:
        wtd.weights(np.log(w[1:]))
        c = NurbsCurve(curve.degree, lay.ctrl(x), w, curve.knots)
        chk = check_curve(c, prob, cfg.n_samples_check)
        return Variant(
            f=obj(x)[0],
            ok=chk.ok,
            length_m=chk.length_m,
            k_max=chk.max_curvature,
            clearance_m=chk.min_clearance_m,
            f_r=f_r(c, req.r_min_m),
        )

    return Comparison(
        plan=variant(x0, curve.weights),
        points=variant(xp, curve.weights),
        joint=variant(xj, wj),
        cpu_points_s=cpu_points,
        cpu_joint_s=cpu_joint,
        w_range=(float(wj.min()), float(wj.max())),
    )


def main(n_varied: int, n_fields: int, max_iter: int) -> list[Comparison]:
    """Print one line per plan and the median gain of the weights; return the comparisons."""
    cfg = PlannerConfig()
    rows = []
    print("F, length m, max curvature 1/m, min clearance m, F_R, check: plan/points only/joint")
    for name, req in requests(n_varied, n_fields):
        o = compare(req, cfg, max_iter)
        if o is None:
            print(f"{name}: NO_PATH")
            continue
        rows.append(o)
        trio = (o.plan, o.points, o.joint)
        cols = [
            "/".join(format(getattr(v, key), fmt) for v in trio)
            for key, fmt in (
                ("f", ".3f"),
                ("length_m", ".2f"),
                ("k_max", ".3f"),
                ("clearance_m", ".2f"),
                ("f_r", ".2f"),
                ("ok", ""),
            )
        ]
        print(
            f"{name}: F {cols[0]} L {cols[1]} k {cols[2]} clr {cols[3]} F_R {cols[4]} "
            f"ok {cols[5]} w in [{o.w_range[0]:.2f}, {o.w_range[1]:.2f}] "
            f"cpu points {1e3 * o.cpu_points_s:.0f} ms, joint {1e3 * o.cpu_joint_s:.0f} ms"
        )
    gain = [o.points.f - o.joint.f for o in rows if o.joint.ok]
    if gain:
        print(
            f"the weights' gain in F where the joint curve passes the check: median "
            f"{np.median(gain):.4f}, max {np.max(gain):.4f} ({len(gain)}/{len(rows)} pass)"
        )
    return rows


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--varied", type=int, default=6, help="varied starts on the default field")
    ap.add_argument("--fields", type=int, default=12, help="random circle fields")
    ap.add_argument("--iter", type=int, default=200, help="iterations of each optimiser")
    a = ap.parse_args()
    main(a.varied, a.fields, a.iter)
