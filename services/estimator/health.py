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
    # and on arrays this small numpy's isfinite/all calls cost five times as much
    return healthy_entries(x.tolist(), P.ravel().tolist())


def healthy_entries(x: list[float], P: list[float]) -> bool:
    """`healthy` of x (n,) and P (n * n,), row-major, as Python floats; P's rows and columns
    may be permuted alike (the answer is the same: a caller reuses a reordered P)."""
    # A sum is finite only if every term is (an inf or a NaN absorbs every later addition):
    # one sum says so for all entries; only a sum that is not (or overflowed) asks each entry
    isfinite = math.isfinite
    d = P[:: len(x) + 1]  # the diagonal
    return (
        (isfinite(sum(x)) or all(map(isfinite, x)))
        and (isfinite(sum(P)) or all(map(isfinite, P)))
        and min(d) >= 0.0
        and max(d) <= MAX_VARIANCE
    )
