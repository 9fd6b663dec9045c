"""Dense final checks of a planned curve: eq. (20) curvature, eq. (12)-(13) clearance, area."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from common.world.geometry import FloatArray
from services.planner.geometry.clearance import moving_distance
from services.planner.geometry.nurbs_curve import NurbsCurve, curvature
from services.planner.shaping.fit import FitProblem
from services.planner.shaping.refine import gauss_legendre
from services.planner.shaping.turning import turn_penalty

FailKind = Literal["", "curvature", "static", "moving", "area"]


@dataclass(frozen=True, kw_only=True)
class CurveCheck:
    """Outcome of the dense check; clearances are hull-to-surface distances (m). A check that
    fails on curvature stops there: its length, turning cost and clearances are not measured
    (nan; no caller reads them of a failed check)."""

    ok: bool
    reason: str
    failed: FailKind  # which constraint failed first ("" when ok)
    length_m: float
    max_curvature: float  # 1/m, over the dense samples
    min_clearance_m: float  # min over static and moving obstacles (moving at t = s / v_ref);
    # samples far from every obstacle report the grid's lower bound, not the exact distance
    min_static_clearance_m: float
    min_moving_clearance_m: float
    turn_penalty: float  # eq. (19) f_R as F_R = int ds / (r - R_min) (inf if any r <= R_min)
    # the curve's points and first two derivatives (3, n, 2) at the n dense parameters, uniform
    # over its domain: its PlannedPath's table when n is the table's size (planned_path.py)
    samples: FloatArray = field(default_factory=lambda: np.zeros((3, 0, 2)), repr=False)


def _gauss_legendre(knots: FloatArray, per_span: int) -> tuple[FloatArray, FloatArray]:
    xg, wg = gauss_legendre(per_span)
    brk = np.unique(knots)
    half = 0.5 * np.diff(brk)
    u = (0.5 * (brk[:-1] + brk[1:]))[:, None] + half[:, None] * xg[None, :]
    return u.ravel(), (half[:, None] * wg[None, :]).ravel()


def check_curve(curve: NurbsCurve, prob: FitProblem, n_samples: int) -> CurveCheck:
    """Sample the curve densely (uniform in u) and test every hard constraint."""
    u = np.linspace(curve.u_min, curve.u_max, n_samples)
    samples = curve.evaluate(u, n_ders=2)
    c, d1, d2 = samples
    k = curvature(d1, d2)
    k_max = float(np.max(k))
    if not np.isfinite(k_max) or k_max >= 1.0 / prob.r_min_m:  # eq. (20), strict
        # most failed rounds fail here (27 of 34 checks in configs/ocean.toml): the rest of
        # the check (exact distances near obstacles, the length's quadrature) would only fill
        # fields no caller reads of a failed check
        return _too_curved(k_max, prob.r_min_m, samples)
    speed = np.hypot(d1[:, 0], d1[:, 1])
    du = np.diff(u)
    s = np.concatenate([[0.0], np.cumsum(0.5 * du * (speed[1:] + speed[:-1]))])
    # reported length by Gauss-Legendre on every knot span (eq. (16)/(18) for the curve)
    uq, wq = _gauss_legendre(curve.knots, 6)
    _, dq1, dq2 = curve.evaluate(uq, n_ders=2)
    ds = wq * np.hypot(dq1[:, 0], dq1[:, 1])
    length = float(np.sum(ds))
    # eq. (19) on the same quadrature; infinite if the dense samples break eq. (20) already
    f_r = (
        turn_penalty(curvature(dq1, dq2), ds, prob.r_min_m)
        if k_max * prob.r_min_m < 1.0
        else math.inf
    )
    # exact static distances only where the grid cannot vouch for the sample: the bilinear
    # clearance is within resolution * sqrt(2) of the exact one (1-Lipschitz, lower-bound grid)
    d_static, _ = prob.grid.static_clearance_at(c)
    need = prob.required(s) - 1e-9
    near = d_static < need + prob.grid.resolution_m * math.sqrt(2.0) + 1e-6
    if near.any():
        d_static[near] = prob.static.distance(c[near])[0]
    d_moving, _ = moving_distance(prob.moving, c, s / prob.v_ref_mps, prob.accel_horizon_s)
    r = prob.vehicle_radius_m
    min_static = float(d_static.min()) - r
    min_moving = float(d_moving.min()) - r
    a = prob.area
    inside = (
        (c[:, 0] >= a.x_min_m + r - 1e-9)
        & (c[:, 0] <= a.x_max_m - r + 1e-9)
        & (c[:, 1] >= a.y_min_m + r - 1e-9)
        & (c[:, 1] <= a.y_max_m - r + 1e-9)
    )
    reason = ""
    failed: FailKind = ""
    if np.any(d_static < need):
        _, reason = _breach("static", d_static, need, c, r)
        failed = "static"
    elif np.any(d_moving < need):
        j, reason = _breach("moving-obstacle", d_moving, need, c, r)
        reason += f", t = {s[j] / prob.v_ref_mps:.1f} s"
        failed = "moving"
    elif not np.all(inside):
        reason = "curve leaves the area"
        failed = "area"
    return CurveCheck(
        ok=not reason,
        reason=reason,
        failed=failed,
        length_m=length,
        max_curvature=k_max,
        min_clearance_m=min(min_static, min_moving),
        min_static_clearance_m=min_static,
        min_moving_clearance_m=min_moving,
        turn_penalty=f_r,
        samples=samples,
    )


def _too_curved(k_max: float, r_min_m: float, samples: FloatArray) -> CurveCheck:
    """The check of a curve that turns tighter than R_min somewhere (eq. (20)): failed there,
    its other measures not taken (nan)."""
    return CurveCheck(
        ok=False,
        reason=(
            f"curvature {k_max:.3f} 1/m >= 1/R_min = {1.0 / r_min_m:.3f} 1/m "
            f"(turning radius {1.0 / max(k_max, 1e-12):.2f} m < R_min = {r_min_m:.2f} m)"
        ),
        failed="curvature",
        length_m=math.nan,
        max_curvature=k_max,
        min_clearance_m=math.nan,
        min_static_clearance_m=math.nan,
        min_moving_clearance_m=math.nan,
        turn_penalty=math.nan,
        samples=samples,
    )


def _breach(what: str, d: FloatArray, need: FloatArray, c: FloatArray, r: float) -> tuple[int, str]:
    """The sample of c (m, 2) that falls furthest short of its required centre-to-surface
    clearance `need` (d: the distances there), and the reason, as hull clearances (r)."""
    j = int(np.argmin(d - need))
    return j, (
        f"{what} clearance {d[j] - r:.2f} m < required {need[j] - r:.2f} m "
        f"at ({c[j, 0]:.1f}, {c[j, 1]:.1f})"
    )
