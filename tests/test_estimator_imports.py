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


UNUSED_PROBE = """
import sys
import services.estimator.core
from services.estimator.filterpy_lazy import LAZY
real = ["filterpy.discrete_bayes.discrete_bayes", "filterpy.gh.gh_filter",
        "filterpy.hinfinity.hinfinity_filter", "filterpy.leastsq.least_squares",
        "filterpy.memory.fading_memory", "filterpy.monte_carlo.resampling"]
print(sorted(LAZY), any(m in sys.modules for m in real), "scipy.ndimage" in sys.modules)
import numpy as np
import filterpy
import filterpy.discrete_bayes
prior = filterpy.discrete_bayes.predict(np.array([0.0, 1.0, 0.0]), 1, [0.0, 1.0, 0.0])
print(prior.tolist(), "scipy.ndimage" in sys.modules)
from filterpy.gh import GHFilter
from filterpy.hinfinity import HInfinityFilter
from filterpy.leastsq import LeastSquaresFilter
from filterpy.memory import FadingMemoryFilter
from filterpy.monte_carlo import systematic_resample
from filterpy.gh import *
print(GHFilter.__module__, HInfinityFilter.__module__, LeastSquaresFilter.__module__,
      FadingMemoryFilter.__module__, systematic_resample.__module__, gh_filter.__name__)
print(filterpy.gh is sys.modules["filterpy.gh"], hasattr(filterpy.gh, "no_such_name"))
"""


def test_the_unused_sub_packages_load_on_first_use() -> None:
    # filterpy's __init__ imports every sub-package: the estimator's start loads none of those
    # it never uses (discrete_bayes would bring scipy.ndimage), and each still works as the
    # real package when asked for a name, star imports included
    out = subprocess.run(
        [sys.executable, "-c", UNUSED_PROBE], capture_output=True, text=True, check=True, timeout=60
    ).stdout.splitlines()
    assert out == [
        "['discrete_bayes', 'gh', 'hinfinity', 'leastsq', 'memory', 'monte_carlo', 'stats']"
        " False False",
        "[0.0, 0.0, 1.0] True",
        "filterpy.gh.gh_filter filterpy.hinfinity.hinfinity_filter filterpy.leastsq.least_squares"
        " filterpy.memory.fading_memory filterpy.monte_carlo.resampling filterpy.gh.gh_filter",
        "True False",
    ]
