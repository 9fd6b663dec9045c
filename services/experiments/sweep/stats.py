"""Confidence intervals of sweep metrics that stay within what each quantity can be: the
bootstrap percentile interval of a mean, Wilson's score interval for a proportion.

A t-interval (mean ± t s / sqrt(n)) is symmetric whatever the data: over 3 seeds of a
quantity that is mostly 0 and never negative it reached below zero (`rho0_breach_m [-0.35,
0.67]`). The percentile interval of the bootstrap means lies within the sample's own range,
so a non-negative quantity gets a non-negative interval and a fraction stays in [0, 1]; its
asymmetry follows the data's skew. Proportions of runs (success, an outcome, a True/False
column) get Wilson's interval, sane at 0 % and 100 %. Neither repairs a small sample: from
fewer than FEW_SEEDS runs the bootstrap interval is too narrow more often than its level
says, which summary.md warns of.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

BOOTSTRAP_RESAMPLES = 4000
# fixed: the same runs give the same intervals, so a regenerated summary is the same file
BOOTSTRAP_SEED = 20260611
FEW_SEEDS = 10  # a cell over fewer runs than this gets a warning: its intervals are rough


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """A sample mean with its two-sided confidence interval [low, high] and sample size."""

    mean: float
    low: float
    high: float
    n: int

    @property
    def half_width(self) -> float:
        return (self.high - self.low) / 2.0

    def text(self, digits: int = 3) -> str:
        """'mean [low, high]' (just the mean for n = 1, '–' without data)."""
        if self.n == 0 or not math.isfinite(self.mean):
            return "–"
        m = f"{self.mean:.{digits}g}"
        if self.n < 2 or not (math.isfinite(self.low) and math.isfinite(self.high)):
            return m
        return f"{m} [{self.low:.2g}, {self.high:.2g}]"


def bootstrap_ci(values: Sequence[float], level: float = 0.95) -> Estimate:
    """Mean and the bootstrap percentile interval of the mean: the (1 - level) / 2 and
    (1 + level) / 2 quantiles of BOOTSTRAP_RESAMPLES resampled means (a fixed seed: the
    same values give the same interval). Within the values' range; nan bounds when n < 2;
    non-finite values are missing ones, not zeros."""
    xs = np.array([float(v) for v in values if math.isfinite(v)])
    n = len(xs)
    if n == 0:
        return Estimate(mean=math.nan, low=math.nan, high=math.nan, n=0)
    # the division can round the mean of equal values one ulp beyond them: keep it in range
    mean = min(max(math.fsum(xs) / n, float(xs.min())), float(xs.max()))
    if n < 2:
        return Estimate(mean=mean, low=math.nan, high=math.nan, n=1)
    rng = np.random.default_rng(BOOTSTRAP_SEED)
    means = xs[rng.integers(0, n, size=(BOOTSTRAP_RESAMPLES, n))].mean(axis=1)
    low, high = np.quantile(means, [(1.0 - level) / 2.0, (1.0 + level) / 2.0])
    # rounding of the resampled means: keep within the sample's range, around its mean
    low = min(max(float(low), float(xs.min())), mean)
    high = max(min(float(high), float(xs.max())), mean)
    return Estimate(mean=mean, low=low, high=high, n=n)


def proportion_ci(values: Sequence[float], level: float = 0.95) -> Estimate:
    """A proportion from 0/1 values (True/False of each run) with Wilson's interval; nan and
    other values are missing."""
    xs = [v for v in values if v in (0.0, 1.0)]
    return wilson(int(sum(xs)), len(xs), level)


def wilson(successes: int, n: int, level: float = 0.95) -> Estimate:
    """Success rate with the Wilson score interval (sane at 0 % and 100 %, unlike mean ± t)."""
    if n == 0:
        return Estimate(mean=math.nan, low=math.nan, high=math.nan, n=0)
    # the normal quantile, scipy.stats's norm.ppf to the bit, without importing scipy.stats
    # (a second of every process that loads a sweep): scipy.special, when it is asked
    from scipy.special import ndtri

    z = float(ndtri((1.0 + level) / 2.0))
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # clamp rounding: at k = 0 or k = n the exact bound is the rate itself
    low, high = max(0.0, min(p, centre - h)), min(1.0, max(p, centre + h))
    return Estimate(mean=p, low=low, high=high, n=n)
