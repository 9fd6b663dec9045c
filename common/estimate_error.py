"""Estimate error: each state estimate against the truth at its stamp, the one rule metrics.json,
the monitor and Foxglove share, so the three show the same number.

The truth at an estimate's stamp is linear between the truth samples around it (position, the
current, and the heading along the unwrapped truth heading, so never across the wrap). An
estimate outside the truth's span is not scored, unless it lies within `hold_s` of the span,
when the nearest end sample stands for the truth (a live view that cannot wait for the next
sample scores provisionally, and scores again when it comes).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import NamedTuple

import numpy as np

from common.messages import StateEstimate, TruthState


class EstimateErrors(NamedTuple):
    """The errors of the n scored estimates (estimate minus truth), in their given order."""

    scored: list[StateEstimate]  # the n estimates within the truth's span (+- hold_s)
    error: np.ndarray  # (n, 3): x (m), y (m), heading (rad, wrapped to [-pi, pi))
    position_m: np.ndarray  # (n,): |(x, y) error|
    current_mps: np.ndarray  # (n,): |(current_x, current_y) error|


def estimate_errors(
    estimates: Sequence[StateEstimate], truth: Sequence[TruthState], *, hold_s: float = 0.0
) -> EstimateErrors:
    """Every estimate within [first truth stamp - hold_s, last + hold_s] against the truth at
    its stamp (module docstring). `truth` in any order (a live stream may reorder it)."""
    if not truth:
        return _errors([], np.empty((0, 3)), np.empty(0))
    ordered = sorted(truth, key=lambda q: q.stamp)  # stable: equal stamps keep their order
    t = np.array([q.stamp for q in ordered])
    lo, hi = t[0] - hold_s, t[-1] + hold_s
    est = [e for e in estimates if lo <= e.stamp <= hi]
    et = np.array([e.stamp for e in est])

    def at(values: Sequence[float]) -> np.ndarray:
        return np.interp(et, t, np.asarray(values))

    theta = np.unwrap([q.theta for q in ordered])
    error = np.column_stack(
        [
            np.array([e.x for e in est]) - at([q.x for q in ordered]),
            np.array([e.y for e in est]) - at([q.y for q in ordered]),
            np.remainder(np.array([e.theta for e in est]) - at(list(theta)) + np.pi, 2 * np.pi)
            - np.pi,
        ]
    )
    current = np.hypot(
        np.array([e.current_x for e in est]) - at([q.current_x for q in ordered]),
        np.array([e.current_y for e in est]) - at([q.current_y for q in ordered]),
    )
    return _errors(est, error, current)


def _errors(est: list[StateEstimate], error: np.ndarray, current: np.ndarray) -> EstimateErrors:
    return EstimateErrors(est, error, np.hypot(error[:, 0], error[:, 1]), current)
