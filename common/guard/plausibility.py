"""Is an input plausible? Its stamp against the receiver's clock, its sizes against the world.

A well-formed message can still be absurd: a fix stamped in Unix time (1.79e9 s) when the
mission clock reads 40 s, a position of 1e300 m, a standard deviation of 1e160. Each would
make a core do unbounded work (predicting across 1.79e9 s) or overflow its arithmetic.
A core judges what it receives against these bounds before using it; the judgement is a
reason string or None, and the core counts and logs the rejections (common.guard.ratelog).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.world import AreaConfig

Reason = Literal["non_finite", "future", "stale", "out_of_range", "too_large"]

# The most obstacles one message may describe (detections of a scan, tracks of a set): the
# paper's world has nine; per-item work (a track filter each) must stay bounded.
MAX_ITEMS = 64
# Clock skew tolerated between a sender and the receiver (the vehicle's watchdog allows
# 0.5 s for commands; a measurement may come from a process whose clock joined later).
MAX_FUTURE_S = 1.0
# Older than this, a measurement says nothing about now (and predicting it forward would
# cost work in proportion to its age).
MAX_AGE_S = 60.0
# Nothing in the water moves faster, turns faster or accelerates harder than this: the
# limits only catch absurd values, never a real manoeuvre.
MAX_SPEED_MPS = 100.0
MAX_RATE_RPS = 10.0
MAX_ACCEL_MPS2 = 100.0


@dataclass(frozen=True, kw_only=True, slots=True)
class Plausibility:
    """The bounds of one world: positions within the operating area grown by one span (its
    larger side) on every side, lengths and position standard deviations up to one span,
    angle standard deviations up to pi, speeds, rates and accelerations up to the physical
    limits above, stamps from max_age_s before to max_future_s after the receiver's time.
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    span_m: float
    max_future_s: float = MAX_FUTURE_S
    max_age_s: float = MAX_AGE_S

    @classmethod
    def of_area(cls, area: AreaConfig) -> Plausibility:
        span = max(area.x_max_m - area.x_min_m, area.y_max_m - area.y_min_m)
        return cls(
            x_min=area.x_min_m - span,
            x_max=area.x_max_m + span,
            y_min=area.y_min_m - span,
            y_max=area.y_max_m + span,
            span_m=span,
        )

    def stamp(self, stamp: float, now: float) -> Reason | None:
        """A stamp must be finite, at most max_future_s ahead of now, at most max_age_s old."""
        if not math.isfinite(stamp):
            return "non_finite"
        if stamp - now > self.max_future_s:
            return "future"
        if now - stamp > self.max_age_s:
            return "stale"
        return None

    def position(self, x: float, y: float) -> Reason | None:
        """A position within the grown area (NaN fails every comparison: out of range)."""
        if self.x_min <= x <= self.x_max and self.y_min <= y <= self.y_max:
            return None
        return "non_finite" if not (math.isfinite(x) and math.isfinite(y)) else "out_of_range"

    def length(self, *values: float) -> Reason | None:
        """Lengths or position standard deviations (m): each in [0, span]."""
        return _within(values, 0.0, self.span_m)

    def angle_std(self, *values: float) -> Reason | None:
        """Angle standard deviations (rad): each in [0, pi] (wider says nothing)."""
        return _within(values, 0.0, math.pi)

    def speed(self, *values: float) -> Reason | None:
        """Speeds or velocity components, or their standard deviations (m/s)."""
        return _within(values, -MAX_SPEED_MPS, MAX_SPEED_MPS)

    def rate(self, *values: float) -> Reason | None:
        """Yaw rates (rad/s)."""
        return _within(values, -MAX_RATE_RPS, MAX_RATE_RPS)

    def accel(self, *values: float) -> Reason | None:
        """Acceleration components (m/s^2)."""
        return _within(values, -MAX_ACCEL_MPS2, MAX_ACCEL_MPS2)

    def delay(self, *values: float) -> Reason | None:
        """One-way delays or their spread (s): each in [-max_future_s, max_age_s] (a sender's
        clock may run up to max_future_s ahead; a delay beyond max_age_s says nothing of now,
        and compensating it would cost work in proportion)."""
        return _within(values, -self.max_future_s, self.max_age_s)

    def angle(self, *values: float) -> Reason | None:
        """Angles (rad): any finite value (they are wrapped where used)."""
        return None if all(math.isfinite(v) for v in values) else "non_finite"

    @staticmethod
    def items(n: int) -> Reason | None:
        """At most MAX_ITEMS obstacles in one message."""
        return "too_large" if n > MAX_ITEMS else None


def _within(values: tuple[float, ...], lo: float, hi: float) -> Reason | None:
    for v in values:
        if not lo <= v <= hi:
            return "out_of_range" if math.isfinite(v) else "non_finite"
    return None


def first_reason(*reasons: Reason | None) -> Reason | None:
    """The first reason that is not None (the checks above, in the caller's order)."""
    for r in reasons:
        if r is not None:
            return r
    return None
