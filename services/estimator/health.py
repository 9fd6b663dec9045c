"""When a Gaussian belief is usable: finite, with variances neither negative nor exploded."""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# A variance beyond this (a standard deviation of 1e6 m, rad, m/s or m/s^2) is a filter that
# has diverged numerically, not a belief about anything in a world of a few km.
MAX_VARIANCE = 1e12


def healthy(x: FloatArray, P: FloatArray) -> bool:
    """Is (x: (n,), P: (n, n)) usable: every entry finite, every variance in [0, MAX_VARIANCE]?

    The wire refuses non-finite numbers and negative variances, so a belief that is not
    healthy could not even be published.
    """
    # checked on Python floats: every track and every vehicle belief is checked each step,
    # and on arrays this small numpy's isfinite/all calls cost five times as much. A sum is
    # finite only if every term is (an inf or a NaN absorbs every later addition): one sum
    # says so for all entries; only a sum that is not (or overflowed) asks each entry
    isfinite = math.isfinite
    xs, ps = x.tolist(), P.ravel().tolist()
    d = P.diagonal().tolist()
    return (
        (isfinite(sum(xs)) or all(map(isfinite, xs)))
        and (isfinite(sum(ps)) or all(map(isfinite, ps)))
        and min(d) >= 0.0
        and max(d) <= MAX_VARIANCE
    )
