"""Eq. (19) f_R, the turning-radius cost, as an integral over arc length.

Eq. (19) sums 1 / (r_k - R_min) over the path's points (infinite if any r_k < R_min), so its
value grows with the number of points. Weighting each point by its share of the length
gives F_R = int ds / (r(s) - R_min) = int k / (1 - R_min k) ds, which does not (points
spaced ds apart: f_R ~ F_R / ds): doubling the samples changes it only by quadrature error.
On gentle bends g = k / (1 - R_min k) ~ |k|, so F_R ~ the total turning (rad); it grows
without bound as a bend's radius approaches R_min.
"""

from __future__ import annotations

import math

import numpy as np

from common.world.geometry import FloatArray

K_SMOOTH_PER_M = 1e-3  # the refinement's F_R smooths |k| over curvatures this small (1/m)


def turn_cost(k: FloatArray, r_min_m: float, k_b: float) -> tuple[FloatArray, FloatArray]:
    """The integrand g = k / (1 - R_min k) of F_R and dg/dk at curvatures k >= 0 (m,), made
    differentiable for an optimiser.

    Eq. (19)'s infinity for r < R_min is left to the curvature hinge of the refinement and
    the dense check of eq. (20): from k_b (< 1/R_min) on g continues as its second-order
    Taylor expansion at k_b, finite everywhere. And g ~ |k| has a kink where a bend changes
    side (the unsigned k is 0 on a straight stretch): k enters as sqrt(k^2 + e^2) - e with
    e = K_SMOOTH_PER_M, which moves F_R by less than e per metre of path.
    """
    root = np.sqrt(k * k + K_SMOOTH_PER_M**2)
    ks = root - K_SMOOTH_PER_M
    kk = np.minimum(ks, k_b)
    den = 1.0 - r_min_m * kk
    g, dg = kk / den, 1.0 / den**2
    over = ks - kk  # > 0 only beyond k_b
    d2g = 2.0 * r_min_m / den**3
    return g + over * (dg + 0.5 * d2g * over), (dg + d2g * over) * (k / root)


def turn_penalty(k: FloatArray, ds: FloatArray, r_min_m: float) -> float:
    """Eq. (19) f_R as the length-weighted integral F_R = sum_j ds_j / (r_j - R_min), from
    curvatures k (m,) and the arc-length weights ds (m,) of a quadrature; infinite if any
    r_j <= R_min (eq. (19)'s second case)."""
    if np.any(k * r_min_m >= 1.0):
        return math.inf
    return float(ds @ (k / (1.0 - r_min_m * k)))
