"""Value checks shared by the config dataclasses' __post_init__; they raise ConfigValueError."""

from __future__ import annotations

import math

from common.config.errors import ConfigValueError


def positive(name: str, x: float) -> None:
    """x must be finite and > 0."""
    if not (math.isfinite(x) and x > 0.0):
        raise ConfigValueError(name, f"{x!r} is invalid, expected a finite value > 0")


def nonneg(name: str, x: float) -> None:
    """x must be finite and >= 0."""
    if not (math.isfinite(x) and x >= 0.0):
        raise ConfigValueError(name, f"{x!r} is invalid, expected a finite value >= 0")


def fraction(name: str, x: float) -> None:
    """x must lie in (0, 1]."""
    if not (math.isfinite(x) and 0.0 < x <= 1.0):
        raise ConfigValueError(name, f"{x!r} is invalid, expected a value in (0, 1]")


def probability(name: str, p: float) -> None:
    """p must lie in [0, 1]."""
    if not (0.0 <= p <= 1.0):
        raise ConfigValueError(name, f"{p!r} is not a probability, expected a value in [0, 1]")


def int_range(name: str, x: int, lo: int, hi: int) -> None:
    """x must be an integer in [lo, hi]."""
    if not (lo <= x <= hi):
        raise ConfigValueError(name, f"{x!r} is out of range, expected an integer in [{lo}, {hi}]")
