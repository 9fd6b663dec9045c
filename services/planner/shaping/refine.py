"""Refinement of the fitted NURBS by the penalised path-length objective of eq. (8)-(9).

Over the free control points x (see fit.Layout) we minimise

    F(x) = L(P) + c_r F_R(P) + c_k sum_j max(0, k_j - k_t)^2 + c_d sum_j max(0, d_t,j - d_j)^2

L is the curve length (eq. (8): a quadrature of |C'|, here Gauss-Legendre on each knot
span), F_R eq. (19)'s turning cost sum 1 / (r_k - R_min) as an integral over arc length on
the same quadrature (turning.py: independent of the sample count), k_j the curvature at
sample j (turning constraint eq. (11) with w_max / v = 1 / R_min, eq. (20)), d_j the
clearance to static obstacles (eq. (12)) and to moving ones where they are when the vehicle
passes, t_j = s_j / v_ref (eq. (13)). Eq. (9)'s hinge max(0, .) is squared so F is smooth;
the targets k_t < 1/R_min and d_t > r + rho0 carry margins so the dense final check passes
strictly. Knots and weights stay fixed: C, C', C'' are linear in P.

Default solver: Levenberg-Marquardt on F with a Gauss-Newton Hessian for the squared hinges
and F_R (each sample's term as the square of its root: the IRLS view of g ~ |k|) and the
majoriser w/|C'| (C'^T C') of the length (the IRLS view of |v|), which gives the flat
"slide along the curve" directions of L the curvature L-BFGS lacks; a step is kept only if
it lowers the true F. scipy's L-BFGS-B on the same F and gradient is the alternative.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from common.config.planner import PlannerConfig
from common.world.geometry import FloatArray
from services.planner.geometry.nurbs_curve import NurbsCurve, rational_basis
from services.planner.shaping.fit import FitProblem, Layout
from services.planner.shaping.turning import turn_cost

_BAND_M = 0.3  # clearance hinges this close to active enter the Hessian model (m)
_BAND_K = 0.1  # curvature hinges within this fraction of the target do too
_LBFGS_STEP_M = 0.05  # L-BFGS-B variable scale: its first step moves the points ~5 cm
_TURN_K_FLOOR = 0.01  # eq. (19) Hessian model: curvature floored here (1/m; r = 100 m)


@dataclass(frozen=True, kw_only=True)
class RefineWeights:
    """Penalty weights c_n of eq. (9) and the targets the refinement aims at."""

    c_d: float  # clearance penalty (m^-1)
    c_k: float  # curvature penalty (m^3)
    clear_margin_m: float  # aim this far beyond the required clearance
    k_target: float  # aim at curvature <= this (1/m), below 1/R_min
    c_r: float = 0.0  # eq. (19) turning cost: metres of length per unit of F_R

    @classmethod
    def of(cls, cfg: PlannerConfig, r_min_m: float) -> RefineWeights:
        """The planner config's penalties and targets, for a vehicle turning on r_min_m."""
        return cls(
            c_d=cfg.penalty_clearance,
            c_k=cfg.penalty_curvature,
            clear_margin_m=cfg.clearance_margin_m,
            k_target=cfg.curvature_margin / r_min_m,
            c_r=cfg.penalty_turn,
        )


@lru_cache(maxsize=16)
def gauss_legendre(n: int) -> tuple[FloatArray, FloatArray]:
    """Gauss-Legendre nodes and weights on [-1, 1] (cached: numpy solves an eigenproblem)."""
    x, w = np.polynomial.legendre.leggauss(n)
    x.setflags(write=False)
    w.setflags(write=False)
    return x, w


def quadrature(knots: FloatArray, per_span: int) -> tuple[FloatArray, FloatArray]:
    """Sample parameters and length weights: Gauss-Legendre nodes on every knot span, plus
    the knots themselves with weight 0.

    For a cubic C'' is piecewise linear with its extremes at the knots, so curvature peaks
    sit near them; sampling only the interior nodes would let the solver hide a peak there.
    """
    xg, wg = gauss_legendre(per_span)
    brk = np.unique(knots)
    lo, hi = brk[:-1], brk[1:]
    u = (0.5 * (lo + hi))[:, None] + (0.5 * (hi - lo))[:, None] * xg[None, :]
    w = (0.5 * (hi - lo))[:, None] * wg[None, :]
    u_all = np.concatenate([u, lo[:, None]], axis=1).ravel()
    w_all = np.concatenate([w, np.zeros((len(lo), 1))], axis=1).ravel()
    u_all, w_all = np.append(u_all, brk[-1]), np.append(w_all, 0.0)
    order = np.argsort(u_all, kind="stable")
    return u_all[order], w_all[order]


def _rows(*terms: tuple[FloatArray, FloatArray]) -> FloatArray:
    """Jacobian rows (m, 2 n) of m sample quantities, each sum_t b_t . (R_t P): for every
    term a (m, 2) weight b and an (m, n) basis matrix R; columns are x0, y0, x1, y1, ..."""
    b0, r0 = terms[0]
    out = np.empty((len(b0), r0.shape[1], 2))  # filled in place: no (m, n, 2) temporaries
    for d in (0, 1):
        np.multiply(b0[:, d, None], r0, out=out[:, :, d])
        for b, r in terms[1:]:
            out[:, :, d] += b[:, d, None] * r
    return out.reshape(len(b0), -1)


@dataclass(frozen=True, slots=True)
class _Point:
    """F at one x, with the sample quantities its derivatives are built from."""

    f: float
    c: FloatArray  # curve points (m, 2)
    v1: FloatArray  # C'
    v2: FloatArray  # C''
    sp: FloatArray  # |C'|
    cross: FloatArray  # x'y'' - y'x''
    k: FloatArray  # curvature
    vk: FloatArray  # its hinge
    turn: tuple[FloatArray, FloatArray, FloatArray] | None  # g(k), g'(k), each sample's F_R
    dists: list[FloatArray]  # clearances: static, then moving
    dirs: list[FloatArray]  # their unit directions away
    hinges: list[FloatArray]  # max(0, d_t - d) of each


class Objective:
    """F(x) of eq. (9) with its gradient and a Gauss-Newton / majoriser Hessian."""

    def __init__(
        self, prob: FitProblem, curve: NurbsCurve, per_span: int, wts: RefineWeights
    ) -> None:
        self.prob, self.wts = prob, wts
        self.lay = Layout(prob, len(curve.ctrl))
        u, self.wq = quadrature(curve.knots, per_span)
        self.r0, self.r1, self.r2 = rational_basis(curve.knots, curve.degree, curve.weights, u, 2)
        # sample times on the starting curve, held for this round (eq. (13): t = s / v_ref)
        d1 = self.r1 @ curve.ctrl
        ds = self.wq * np.hypot(d1[:, 0], d1[:, 1])
        s = np.cumsum(ds) - 0.5 * ds
        self.d_t = prob.required(s) + wts.clear_margin_m
        t_s = s / prob.v_ref_mps
        self.centres = np.zeros((len(prob.moving), len(u), 2))  # alpha_k(t_j), eq. (12)
        for i, o in enumerate(prob.moving):
            self.centres[i] = o.centre_at(t_s, prob.accel_horizon_s)
        self.radii = np.array([o.radius for o in prob.moving])[:, None]

    def __call__(
        self, x: FloatArray, hessian: bool = False
    ) -> tuple[float, FloatArray, FloatArray]:
        """F(x), dF/dx and (if asked) the PSD Hessian model; the last is empty otherwise."""
        at = self.value(x)
        gx, h = self.derivatives(at, hessian)
        return at.f, gx, h

    def value(self, x: FloatArray) -> _Point:
        """F(x) alone, with what its derivatives reuse: a trial step that does not lower F
        needs no more (Levenberg-Marquardt rejects a third of its steps)."""
        wts = self.wts
        p = self.lay.ctrl(x)
        c, v1, v2 = self.r0 @ p, self.r1 @ p, self.r2 @ p
        sp = np.maximum(np.hypot(v1[:, 0], v1[:, 1]), 1e-9)
        f = float(self.wq @ sp)  # eq. (8): length
        # eq. (19)-(20): curvature k = |x'y'' - y'x''| / |C'|^3 and its hinge
        cross = v1[:, 0] * v2[:, 1] - v1[:, 1] * v2[:, 0]
        k = np.abs(cross) / sp**3
        vk = np.maximum(k - wts.k_target, 0.0)
        f += wts.c_k * float(vk @ vk)
        turn = None
        if wts.c_r > 0.0:  # eq. (19): c_r F_R, F_R = int g(k) ds with ds = |C'| du (turn_cost)
            gk, dgk = turn_cost(k, self.prob.r_min_m, wts.k_target)
            fr = wts.c_r * self.wq * sp * gk
            f += float(np.sum(fr))
            turn = (gk, dgk, fr)
        dists, dirs = self._clearances(c)
        hinges = []
        for dist_m in dists:
            vd = np.maximum(self.d_t - dist_m, 0.0)
            f += wts.c_d * float(vd @ vd)
            hinges.append(vd)
        return _Point(f, c, v1, v2, sp, cross, k, vk, turn, dists, dirs, hinges)

    def derivatives(self, at: _Point, hessian: bool = False) -> tuple[FloatArray, FloatArray]:
        """dF/dx at a point `value` gave and (if asked) the PSD Hessian model, else empty."""
        wts = self.wts
        v1, v2, sp, k, vk = at.v1, at.v2, at.sp, at.k, at.vk
        g1 = (self.wq / sp)[:, None] * v1
        sg = np.sign(at.cross) / sp**3
        kk = 3.0 * k / sp**2
        dk1 = np.stack([sg * v2[:, 1] - kk * v1[:, 0], -sg * v2[:, 0] - kk * v1[:, 1]], axis=1)
        dk2 = np.stack([-sg * v1[:, 1], sg * v1[:, 0]], axis=1)
        g1 += (2.0 * wts.c_k * vk)[:, None] * dk1
        g2 = (2.0 * wts.c_k * vk)[:, None] * dk2
        turn_rows = None
        if at.turn is not None:
            gk, dgk, fr = at.turn
            ws = wts.c_r * self.wq
            a1 = (ws * gk / sp)[:, None] * v1 + (ws * sp * dgk)[:, None] * dk1
            a2 = (ws * sp * dgk)[:, None] * dk2
            g1 += a1
            g2 += a2
            if hessian:
                turn_rows = (fr, a1, a2)
        gc = np.zeros_like(at.c)
        for vd, dd in zip(at.hinges, at.dirs, strict=True):
            gc -= (2.0 * wts.c_d * vd)[:, None] * dd
        gp = self.r0.T @ gc + self.r1.T @ g1 + self.r2.T @ g2
        gx = self.lay.m.T @ gp.ravel()
        if not hessian:
            return gx, np.zeros((0, 0))
        hp = self._hessian_model(sp, k, dk1, dk2, at.dists, at.dirs, turn_rows)
        return gx, self.lay.m.T @ hp @ self.lay.m

    def _clearances(self, c: FloatArray) -> tuple[list[FloatArray], list[FloatArray]]:
        """eq. (12)-(13): the samples' (m,) clearances to static (bilinear grid) and moving
        (exact, the nearest per sample) obstacles, with their (m, 2) unit directions away."""
        dist, grad = self.prob.grid.static_clearance_at(c)
        dists, dirs = [dist], [grad]
        if len(self.centres):
            diff = c[None, :, :] - self.centres
            rr = np.maximum(np.hypot(diff[..., 0], diff[..., 1]), 1e-9)
            dm = rr - self.radii
            kmin = np.argmin(dm, axis=0)  # nearest moving obstacle per sample
            cols = np.arange(len(c))
            dists.append(dm[kmin, cols])
            dirs.append(diff[kmin, cols] / rr[kmin, cols][:, None])
        return dists, dirs

    def _hessian_model(
        self,
        sp: FloatArray,
        k: FloatArray,
        dk1: FloatArray,
        dk2: FloatArray,
        dists: list[FloatArray],
        dirs: list[FloatArray],
        turn_rows: tuple[FloatArray, FloatArray, FloatArray] | None,
    ) -> FloatArray:
        """The PSD Hessian model (2 n, 2 n) on the control points: the length majoriser plus
        Gauss-Newton rows of the active hinges and the turning cost."""
        wts, n = self.wts, self.lay.n
        # length majoriser: sum_j (w_j / |C'_j|) C'_j^T C'_j, the same for x and y
        kmat = self.r1.T @ ((self.wq / sp)[:, None] * self.r1)
        hp = np.zeros((2 * n, 2 * n))
        hp[0::2, 0::2] = kmat
        hp[1::2, 1::2] = kmat
        # Gauss-Newton rows sqrt(2c) dv/dP of the hinges. Hinges within a small band of
        # becoming active are included too: the model then "sees" a wall the step is about
        # to hit instead of overshooting into it and being rejected.
        rows = []
        act = k > wts.k_target * (1.0 - _BAND_K)
        if act.any():
            ck = np.sqrt(2.0 * wts.c_k)
            rows.append(_rows((ck * dk1[act], self.r1[act]), (ck * dk2[act], self.r2[act])))
        for dist_m, dd in zip(dists, dirs, strict=True):
            act = dist_m < self.d_t + _BAND_M
            if act.any():
                rows.append(_rows((np.sqrt(2.0 * wts.c_d) * dd[act], self.r0[act])))
        if turn_rows is not None:
            # Gauss-Newton on f_j = (sqrt f_j)^2: rows grad f_j / sqrt(2 f_j), the IRLS
            # majoriser of g ~ |k|; the floor keeps nearly straight samples from freezing
            fr, a1, a2 = turn_rows
            floor = wts.c_r * self.wq * sp * _TURN_K_FLOOR
            sc = np.divide(
                1.0, np.sqrt(2.0 * np.maximum(fr, floor)), where=floor > 0.0, out=np.zeros_like(fr)
            )
            rows.append(_rows((sc[:, None] * a1, self.r1), (sc[:, None] * a2, self.r2)))
        if rows:
            jac = np.concatenate(rows)
            hp += jac.T @ jac
        return hp


def levenberg_marquardt(
    obj: Objective, x0: FloatArray, lo: FloatArray, hi: FloatArray, max_iter: int
) -> FloatArray:
    """Damped Newton steps on the Hessian model, projected on the box, kept if F drops."""
    x = np.clip(x0, lo, hi)
    f, g, h = obj(x, hessian=True)
    lam = 1.0
    eye = np.eye(len(x))
    # the damping's matrix and -g change only with a step kept: a rejected step (a third of
    # them) retries the same with a larger lam
    damp, neg_g = np.diag(np.diag(h)) + 1e-6 * eye, -g
    for _ in range(max_iter):
        step = np.linalg.solve(h + lam * damp, neg_g)
        xn = np.minimum(np.maximum(x + step, lo), hi)
        at = obj.value(xn)  # the derivatives only for a step that is kept
        fn = at.f
        if fn < f:
            done = f - fn < 1e-6 * abs(f)
            gn, h = obj.derivatives(at, hessian=True)
            x, f = xn, fn
            lam = max(lam / 3.0, 1e-9)
            if done:
                break
            damp, neg_g = np.diag(np.diag(h)) + 1e-6 * eye, -gn
        else:
            lam *= 8.0
            if lam > 1e6:
                break
    return x


def lbfgsb(
    obj: Objective, x0: FloatArray, lo: FloatArray, hi: FloatArray, max_iter: int
) -> FloatArray:
    """scipy L-BFGS-B on F, in variables scaled so its first step is a few centimetres."""
    # imported here: scipy.optimize costs every process ~70 ms to import, and only this
    # alternative solver needs it
    from scipy.optimize import minimize

    x0 = np.clip(x0, lo, hi)
    sc = _LBFGS_STEP_M

    def fun(z: FloatArray) -> tuple[float, FloatArray]:
        f, g, _ = obj(x0 + sc * z)
        return f, sc * g

    bounds = list(zip(((lo - x0) / sc).tolist(), ((hi - x0) / sc).tolist(), strict=True))
    res = minimize(
        fun,
        np.zeros_like(x0),
        jac=True,
        method="L-BFGS-B",
        bounds=bounds,
        options={"maxiter": max_iter},
    )
    return np.asarray(x0 + sc * res.x)


def refine(
    prob: FitProblem,
    curve: NurbsCurve,
    wts: RefineWeights,
    *,
    per_span: int,
    max_iter: int,
    method: str = "levenberg_marquardt",
) -> NurbsCurve:
    """One refinement round: minimise eq. (9) over the free control points."""
    obj = Objective(prob, curve, per_span, wts)
    lay = obj.lay
    # the area's edge gets the allowance obstacles get (the hull tracked off its path by the
    # margin stays in; eq. (10) itself asks only the hull inside, as the final check does):
    # on a path grazing the edge, a pose predicted ahead can fall just outside the area,
    # from where no replan can start
    a = prob.area
    room = 0.5 * min(a.x_max_m - a.x_min_m, a.y_max_m - a.y_min_m)
    edge_m = min(prob.vehicle_radius_m + wts.clear_margin_m, max(prob.vehicle_radius_m, room))
    lo, hi = lay.bounds(a, edge_m, 4.0 * prob.r_min_m + 10.0)
    x0 = lay.to_x(curve.ctrl)
    if max_iter > 0 and lay.dim:
        solve = lbfgsb if method == "lbfgsb" else levenberg_marquardt
        x0 = solve(obj, x0, lo, hi, max_iter)
    return NurbsCurve(curve.degree, lay.ctrl(x0), curve.weights, curve.knots)
