"""The NURBS curve math, on the curve parameter u: knots, basis, derivatives, curvature.

Knot vectors, the vectorised Cox-de Boor basis, rational derivatives and eq. (20) curvature.

Everything is evaluated for many parameters at once: the p + 1 non-zero basis functions and
their derivatives come from the Cox-de Boor triangle run on (m,) arrays, and the rational
basis R_i = w_i N_i / W from the quotient rule. C^(k)(u) = R^(k)(u) @ P, so every
derivative is linear in the control points (the refinement relies on that).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from common.world.geometry import FloatArray

IntArray = NDArray[np.intp]


@dataclass(frozen=True, eq=False)
class NurbsCurve:
    """A planar NURBS curve of eq. (19)-(20): degree p, control points, weights, knots."""

    degree: int
    ctrl: FloatArray  # (n, 2) control points
    weights: FloatArray  # (n,) positive weights
    knots: FloatArray  # (n + p + 1,) non-decreasing

    def __post_init__(self) -> None:
        n, p = len(self.ctrl), self.degree
        if p < 1 or n <= p:
            raise ValueError(f"nurbs: {n} control points cannot carry a degree-{p} curve")
        if self.ctrl.shape != (n, 2) or self.weights.shape != (n,):
            raise ValueError("nurbs: control points must be (n, 2) with n weights")
        if len(self.knots) != n + p + 1 or np.any(np.diff(self.knots) < 0.0):
            raise ValueError(f"nurbs: expected {n + p + 1} non-decreasing knots")
        if np.any(self.weights <= 0.0):
            raise ValueError("nurbs: weights must be > 0")

    @property
    def u_min(self) -> float:
        return float(self.knots[self.degree])

    @property
    def u_max(self) -> float:
        return float(self.knots[-self.degree - 1])

    def evaluate(self, u: FloatArray, n_ders: int = 2) -> FloatArray:
        """Points and derivatives (n_ders + 1, m, 2) of the rational curve at parameters u."""
        idx, loc = rational_local(self.knots, self.degree, self.weights, u, n_ders)
        return np.einsum("kmj,mjd->kmd", loc, self.ctrl[idx])


def clamped_uniform_knots(n_ctrl: int, degree: int) -> FloatArray:
    """Clamped (open) uniform knot vector on [0, 1]: p+1 zeros, uniform interior, p+1 ones."""
    interior = np.linspace(0.0, 1.0, n_ctrl - degree + 1)[1:-1]
    return np.concatenate([np.zeros(degree + 1), interior, np.ones(degree + 1)])


def averaged_knots(points: FloatArray, degree: int) -> FloatArray:
    """Clamped knots on [0, 1] by de Boor's averaging of chord-length parameters of `points`."""
    n = len(points)
    chord = np.hypot(*np.diff(points, axis=0).T)
    if chord.sum() <= 0.0:
        return clamped_uniform_knots(n, degree)
    t = np.concatenate([[0.0], np.cumsum(chord)]) / chord.sum()
    if n - degree - 1 <= 0:  # a single Bezier segment: no interior knots
        return clamped_uniform_knots(n, degree)
    win = np.lib.stride_tricks.sliding_window_view(t[1:-1], degree)
    interior = win.mean(axis=1)[: n - degree - 1]
    return np.concatenate([np.zeros(degree + 1), interior, np.ones(degree + 1)])


def join(a: NurbsCurve, b: NurbsCurve, split: float) -> NurbsCurve:
    """Curve a then curve b as one curve on [0, 1], a on [0, split] and b on [split, 1].

    Both clamped, of one degree p, a ending where b starts. The joint knot gets multiplicity
    p, so each piece keeps its own shape (C0 at the joint; G1 when the end tangents agree);
    b's weights are scaled so that the shared control point has a's weight (a rational piece
    does not change when all its weights are scaled by one factor).
    """
    p = a.degree
    if b.degree != p:
        raise ValueError(f"join: degrees differ ({p} and {b.degree})")
    for c in (a, b):
        if np.ptp(c.knots[: p + 1]) > 0.0 or np.ptp(c.knots[-p - 1 :]) > 0.0:
            raise ValueError("join: both curves must have clamped knot vectors")
    if not np.allclose(a.ctrl[-1], b.ctrl[0], rtol=0.0, atol=1e-9):
        raise ValueError("join: the first curve must end where the second starts")
    if not 0.0 < split < 1.0:
        raise ValueError(f"join: split {split!r} must lie in (0, 1)")
    ka = (a.knots - a.knots[0]) / (a.knots[-1] - a.knots[0]) * split
    kb = split + (b.knots - b.knots[0]) / (b.knots[-1] - b.knots[0]) * (1.0 - split)
    wb = b.weights * (a.weights[-1] / b.weights[0])
    return NurbsCurve(
        p,
        np.concatenate([a.ctrl, b.ctrl[1:]]),
        np.concatenate([a.weights, wb[1:]]),
        np.concatenate([ka[:-1], kb[p + 1 :]]),
    )


def find_spans(knots: FloatArray, degree: int, u: FloatArray) -> IntArray:
    """Knot span index i with u_i <= u < u_{i+1} for each u (the last span is closed)."""
    n_ctrl = len(knots) - degree - 1
    span = np.searchsorted(knots, u, side="right") - 1
    return np.clip(span, degree, n_ctrl - 1).astype(np.intp)


def basis_local(
    knots: FloatArray, degree: int, u: FloatArray, n_ders: int = 2
) -> tuple[IntArray, FloatArray]:
    """Non-zero B-spline basis functions and derivatives at many parameters at once.

    Returns the spans (m,) and ders (n_ders + 1, m, p + 1): ders[k, j, r] is the k-th
    derivative of N_{span_j - p + r, p} at u_j. This is the Cox-de Boor triangle of
    The NURBS Book A2.3 with every scalar replaced by an (m,) array; its denominators are
    lengths of knot intervals that contain the (non-empty) span, so they never vanish.
    """
    p = degree
    kn = np.asarray(knots, dtype=np.float64)
    u = np.clip(np.atleast_1d(np.asarray(u, dtype=np.float64)), kn[p], kn[len(kn) - p - 1])
    m = len(u)
    span = find_spans(kn, p, u)
    ndu = np.empty((p + 1, p + 1, m))
    ndu[0, 0] = 1.0
    left = np.empty((p + 1, m))
    right = np.empty((p + 1, m))
    for j in range(1, p + 1):
        left[j] = u - kn[span + 1 - j]
        right[j] = kn[span + j] - u
        saved = np.zeros(m)
        for r in range(j):
            ndu[j, r] = right[r + 1] + left[j - r]  # lower triangle: knot differences
            temp = ndu[r, j - 1] / ndu[j, r]
            ndu[r, j] = saved + right[r + 1] * temp  # upper triangle: basis functions
            saved = left[j - r] * temp
        ndu[j, j] = saved
    ders = np.zeros((n_ders + 1, m, p + 1))
    ders[0] = ndu[:, p].T
    top = min(n_ders, p)
    a = np.empty((2, p + 1, m))
    for r in range(p + 1):
        s1, s2 = 0, 1
        a[0, 0] = 1.0
        for k in range(1, top + 1):
            d = np.zeros(m)
            rk, pk = r - k, p - k
            if r >= k:
                a[s2, 0] = a[s1, 0] / ndu[pk + 1, rk]
                d = a[s2, 0] * ndu[rk, pk]
            j1 = 1 if rk >= -1 else -rk
            j2 = k - 1 if r - 1 <= pk else p - r
            for j in range(j1, j2 + 1):
                a[s2, j] = (a[s1, j] - a[s1, j - 1]) / ndu[pk + 1, rk + j]
                d = d + a[s2, j] * ndu[rk + j, pk]
            if r <= pk:
                a[s2, k] = -a[s1, k - 1] / ndu[pk + 1, r]
                d = d + a[s2, k] * ndu[r, pk]
            ders[k, :, r] = d
            s1, s2 = s2, s1
    factor = float(p)
    for k in range(1, top + 1):  # multiply by p! / (p - k)!
        ders[k] *= factor
        factor *= p - k
    return span, ders


def rational_local(
    knots: FloatArray, degree: int, weights: FloatArray, u: FloatArray, n_ders: int = 2
) -> tuple[IntArray, FloatArray]:
    """Non-zero rational basis R^(k) (n_ders + 1, m, p + 1) and control-point indices (m, p + 1).

    Quotient rule, with W = sum w_i N_i:
    R = w N / W,  R' = (w N' - W' R) / W,  R'' = (w N'' - 2 W' R' - W'' R) / W.
    """
    if n_ders > 2:
        raise ValueError("rational_local: at most second derivatives are supported")
    span, nd = basis_local(knots, degree, u, n_ders)
    idx = span[:, None] - degree + np.arange(degree + 1)[None, :]
    wl = weights[idx]
    wsum = np.einsum("kmj,mj->km", nd, wl)  # W, W', W''
    out = np.empty_like(nd)
    out[0] = nd[0] * wl / wsum[0][:, None]
    if n_ders >= 1:
        out[1] = (nd[1] * wl - wsum[1][:, None] * out[0]) / wsum[0][:, None]
    if n_ders >= 2:
        out[2] = (nd[2] * wl - 2.0 * wsum[1][:, None] * out[1] - wsum[2][:, None] * out[0]) / wsum[
            0
        ][:, None]
    return idx, out


def rational_basis(
    knots: FloatArray, degree: int, weights: FloatArray, u: FloatArray, n_ders: int = 2
) -> list[FloatArray]:
    """Dense rational basis matrices R^(k) (m, n_ctrl), k = 0..n_ders: C^(k) = R^(k) @ P."""
    idx, loc = rational_local(knots, degree, weights, u, n_ders)
    m = idx.shape[0]
    rows = np.arange(m)[:, None]
    out = []
    for k in range(n_ders + 1):
        dense = np.zeros((m, len(weights)))
        dense[rows, idx] = loc[k]
        out.append(dense)
    return out


def curvature(d1: FloatArray, d2: FloatArray) -> FloatArray:
    """Unsigned curvature k = |x'y'' - y'x''| / |r'|^3 (eq. (20)); inf where r' vanishes."""
    cross = np.abs(d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0])
    speed3 = np.hypot(d1[:, 0], d1[:, 1]) ** 3
    out = np.full(len(cross), np.inf)
    np.divide(cross, speed3, out=out, where=speed3 > 1e-300)
    return out
