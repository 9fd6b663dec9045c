"""The estimator imports filterpy without scipy.stats (services/estimator/filterpy_lazy.py)."""

from __future__ import annotations

import subprocess
import sys

PROBE = """
import sys
import services.estimator.core
print("scipy.stats" in sys.modules)
import numpy as np
from filterpy.kalman import KalmanFilter
kf = KalmanFilter(dim_x=2, dim_z=1)
kf.H = np.array([[1.0, 0.0]])
kf.update(np.array([1.0]))
print(round(kf.log_likelihood, 6), "scipy.stats" in sys.modules)
"""


def test_the_estimator_starts_without_scipy_stats_and_likelihoods_still_load_it() -> None:
    out = subprocess.run(
        [sys.executable, "-c", PROBE], capture_output=True, text=True, check=True, timeout=60
    ).stdout.split()
    # a unit innovation with unit variance: log N(1; 0, 2) = -ln(2 sqrt(pi)) - 1/4
    assert out == ["False", "-1.515512", "True"]
