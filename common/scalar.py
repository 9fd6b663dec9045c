"""Two scalar helpers every service shares: the one angle wrap and the one clamp."""

from __future__ import annotations

import math

_TWO_PI = 2.0 * math.pi


def wrap_angle(a: float) -> float:
    """Angle a (rad) wrapped to [-pi, pi]: IEEE remainder by 2 pi, exact (no rounding).

    Unchanged, bit for bit, when a is already inside [-pi, pi].
    """
    return math.remainder(a, _TWO_PI)


def clamp(x: float, lo: float, hi: float) -> float:
    """x limited to [lo, hi] (returned unchanged when inside)."""
    return lo if x < lo else hi if x > hi else x
