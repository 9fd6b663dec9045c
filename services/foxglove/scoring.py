"""Estimate error for the Foxglove view: each published estimate against the truth at its stamp.

An estimate is stamped at the estimator's step, and a watcher often gets it before the truth
sample of that same instant: estimates wait here until the truth has reached their stamp.
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from common.scalar import wrap_angle


class Scored(NamedTuple):
    """An estimate's error: position (m) and heading (rad, estimate minus truth), at t (s)."""

    t: float
    error_m: float
    heading_error_rad: float


class EstimateScorer:
    """Holds the recent truth and the estimates it has not reached yet."""

    def __init__(self, *, truth_memory_s: float = 30.0, max_waiting: int = 200) -> None:
        self.truth_memory_s = truth_memory_s
        self._truth: deque[tuple[float, float, float, float]] = deque()  # t, x, y, theta
        # bounded: a stalled truth stream must not grow it for ever
        self._waiting: deque[tuple[float, float, float, float]] = deque(maxlen=max_waiting)

    def truth(self, t: float, x: float, y: float, theta: float) -> list[Scored]:
        """Note a truth sample; the estimates it lets us score."""
        self._truth.append((t, x, y, theta))
        while self._truth[0][0] < t - self.truth_memory_s:
            self._truth.popleft()
        return self._score()

    def estimate(self, t: float, x: float, y: float, theta: float) -> list[Scored]:
        """Note an estimate; the estimates (it among them) the truth lets us score now."""
        self._waiting.append((t, x, y, theta))
        return self._score()

    def _score(self) -> list[Scored]:
        """Every waiting estimate the truth has reached, against the truth at its stamp:
        position linear between the samples around it, heading of the sample at or after
        it (no interpolation across the wrap). One older than the truth held is dropped."""
        out: list[Scored] = []
        if not self._truth:
            return out
        arr: np.ndarray | None = None
        while self._waiting and self._waiting[0][0] <= self._truth[-1][0]:
            t, x, y, theta = self._waiting.popleft()
            if t < self._truth[0][0]:
                continue
            if arr is None:
                arr = np.asarray(self._truth)
            tx = float(np.interp(t, arr[:, 0], arr[:, 1]))
            ty = float(np.interp(t, arr[:, 0], arr[:, 2]))
            i = min(int(np.searchsorted(arr[:, 0], t)), len(arr) - 1)
            out.append(Scored(t, math.hypot(x - tx, y - ty), wrap_angle(theta - float(arr[i, 3]))))
        return out
