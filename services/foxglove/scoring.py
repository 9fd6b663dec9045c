"""Estimate error for the Foxglove view: each published estimate against the truth at its stamp.

An estimate is stamped at the estimator's step, and a watcher often gets it before the truth
sample of that same instant: estimates wait here until the truth has reached their stamp, and
are then scored by the rule metrics.json and the monitor share (common/estimate_error.py).
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

from common.estimate_error import estimate_errors
from common.messages import StateEstimate, TruthState


class Scored(NamedTuple):
    """An estimate's error: position (m) and heading (rad, estimate minus truth), at t (s)."""

    t: float
    error_m: float
    heading_error_rad: float


class EstimateScorer:
    """Holds the recent truth and the estimates it has not reached yet."""

    def __init__(self, *, truth_memory_s: float = 30.0, max_waiting: int = 200) -> None:
        self.truth_memory_s = truth_memory_s
        self._truth: deque[TruthState] = deque()
        # bounded: a stalled truth stream must not grow it for ever
        self._waiting: deque[StateEstimate] = deque(maxlen=max_waiting)

    def truth(self, msg: TruthState) -> list[Scored]:
        """Note a truth sample; the estimates it lets us score."""
        self._truth.append(msg)
        while self._truth[0].stamp < msg.stamp - self.truth_memory_s:
            self._truth.popleft()
        return self._score()

    def estimate(self, msg: StateEstimate) -> list[Scored]:
        """Note an estimate; the estimates (it among them) the truth lets us score now."""
        self._waiting.append(msg)
        return self._score()

    def _score(self) -> list[Scored]:
        """Every waiting estimate the truth has reached, against the truth at its stamp; one
        older than the truth held is dropped."""
        if not self._truth:
            return []
        reached = max(q.stamp for q in self._truth)
        ready: list[StateEstimate] = []
        while self._waiting and self._waiting[0].stamp <= reached:
            ready.append(self._waiting.popleft())
        if not ready:
            return []
        errors = estimate_errors(ready, self._truth)
        return [
            Scored(e.stamp, float(pos), float(err[2]))
            for e, pos, err in zip(errors.scored, errors.position_m, errors.error, strict=True)
        ]
