"""Confidence intervals of sweep metrics: t-distribution for means, Wilson for success rates."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from scipy import stats as st


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
        """'mean ± half-width' (just the mean for n = 1, '–' without data)."""
        if self.n == 0 or not math.isfinite(self.mean):
            return "–"
        m = f"{self.mean:.{digits}g}"
        if self.n < 2 or not math.isfinite(self.half_width):
            return m
        return f"{m} ± {self.half_width:.2g}"


def mean_ci(values: Sequence[float], level: float = 0.95) -> Estimate:
    """Mean and t-interval mean ± t_{(1+level)/2, n-1} s / sqrt(n); nan bounds when n < 2."""
    xs = [float(v) for v in values if math.isfinite(v)]
    n = len(xs)
    if n == 0:
        return Estimate(mean=math.nan, low=math.nan, high=math.nan, n=0)
    mean = math.fsum(xs) / n
    if n < 2:
        return Estimate(mean=mean, low=math.nan, high=math.nan, n=1)
    sd = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    h = float(st.t.ppf((1.0 + level) / 2.0, n - 1)) * sd / math.sqrt(n)
    return Estimate(mean=mean, low=mean - h, high=mean + h, n=n)


def wilson(successes: int, n: int, level: float = 0.95) -> Estimate:
    """Success rate with the Wilson score interval (sane at 0 % and 100 %, unlike mean ± t)."""
    if n == 0:
        return Estimate(mean=math.nan, low=math.nan, high=math.nan, n=0)
    z = float(st.norm.ppf((1.0 + level) / 2.0))
    p = successes / n
    denom = 1.0 + z * z / n
    centre = (p + z * z / (2 * n)) / denom
    h = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / denom
    # clamp rounding: at k = 0 or k = n the exact bound is the rate itself
    low, high = max(0.0, min(p, centre - h)), min(1.0, max(p, centre + h))
    return Estimate(mean=p, low=low, high=high, n=n)
