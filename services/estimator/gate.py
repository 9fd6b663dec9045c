"""The chi-square gate on an innovation: does a measurement agree with a Gaussian belief?"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.special import chdtri

FloatArray = NDArray[np.float64]


class ChiSquareGate:
    """Accepts an innovation y with covariance S while its squared Mahalanobis distance
    y' S^-1 y is within the chi-square quantile of `probability` (`dof` degrees of freedom)."""

    def __init__(self, probability: float, dof: int = 2) -> None:
        # chdtri: the inverse survival function; scipy.special rather than scipy.stats, whose
        # import alone costs every service process over a second
        self.threshold = float(chdtri(dof, 1.0 - probability))

    def accepts(self, y: FloatArray, S: FloatArray) -> bool:
        """Is y' S^-1 y within the threshold? y: (k,) innovation, S: (k, k) its covariance."""
        return float(y @ np.linalg.solve(S, y)) <= self.threshold
