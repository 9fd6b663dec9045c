"""The chi-square gate on an innovation: does a measurement agree with a Gaussian belief?"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


class ChiSquareGate:
    """Accepts an innovation y with covariance S while its squared Mahalanobis distance
    y' S^-1 y is within the chi-square quantile of `probability` (`dof` degrees of freedom)."""

    def __init__(self, probability: float, dof: int = 2) -> None:
        self.threshold = chi2_quantile(probability, dof)

    def accepts(self, y: FloatArray, S: FloatArray) -> bool:
        """Is y' S^-1 y within the threshold? y: (k,) innovation, S: (k, k) its covariance."""
        return float(y @ np.linalg.solve(S, y)) <= self.threshold


def chi2_quantile(probability: float, dof: int) -> float:
    """The chi-square quantile of `probability` with `dof` degrees of freedom. Two (a
    position) in closed form, -2 ln(1 - p): scipy.special, whose import costs every estimator
    process ~0.4 s, only for the others."""
    if dof == 2:
        return -2.0 * math.log1p(-probability)
    from scipy.special import chdtri  # the inverse survival function

    return float(chdtri(dof, 1.0 - probability))
