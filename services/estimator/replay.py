"""Out-of-sequence fusion: a stamp-ordered measurement buffer that rolls back and re-fuses."""

from __future__ import annotations

import bisect
from collections.abc import Callable
from dataclasses import dataclass
from typing import Generic, TypeVar

S = TypeVar("S")  # an immutable filter state (never modified once built)
M = TypeVar("M")  # a measurement


@dataclass(kw_only=True, slots=True)
class _Entry(Generic[M, S]):
    key: tuple[float, int]  # (stamp, seq): the fusion order, independent of arrival order
    meas: M
    before: S  # the state this measurement was fused into


class ReplayBuffer(Generic[M, S]):
    """Fuses every measurement at its sampling time (stamp), whatever its arrival order.

    A measurement newer than all others is fused at once. An older one (delayed) is
    inserted at its place: the state is rolled back to the one it should have been fused
    into and every later measurement is fused again (as robot_localization does for lagged
    data), so the result equals in-order fusion exactly. Measurements more than history_s
    older than the newest are rejected (their state is no longer kept); a (stamp, seq)
    already in the buffer is a duplicate and dropped.

    At most max_entries are kept (the oldest go first), so neither memory nor the work of
    one replay grows with a flood of measurements inside the window; a measurement older
    than the oldest kept one is then rejected as too old too. `cost` says beforehand how
    much work an `add` would do, so a caller can refuse work beyond a budget.
    """

    def __init__(
        self,
        initial: S,
        apply: Callable[[S, M], S],
        history_s: float,
        *,
        max_entries: int = 256,
        weight: Callable[[M], int] = lambda m: 1,
    ) -> None:
        self._apply = apply
        self._history_s = history_s
        self._max_entries = max_entries
        self._weight = weight  # the work of fusing one measurement, in the caller's units
        self._entries: list[_Entry[M, S]] = []
        self._keys: list[tuple[float, int]] = []
        self._newest = float("-inf")
        self._floor: tuple[float, int] | None = None  # key of the newest entry dropped by count
        self.state: S = initial  # after every buffered measurement
        self.fused = 0  # measurements accepted
        self.rejected_old = 0
        self.duplicates = 0
        self.replays = 0  # out-of-order insertions that re-fused later measurements
        self.refused = 0  # later measurements fused again by those replays

    def _too_old(self, key: tuple[float, int]) -> bool:
        return key[0] < self._newest - self._history_s or (
            self._floor is not None and key <= self._floor
        )

    def cost(self, meas: M, stamp: float, seq: int = 0) -> int:
        """The work `add` would do now: the weight of meas and of every later measurement it
        would fuse again (0 when it would be rejected)."""
        key = (stamp, seq)
        if self._too_old(key):
            return 0
        i = bisect.bisect_left(self._keys, key)
        if i < len(self._keys) and self._keys[i] == key:
            return 0
        return self._weight(meas) + sum(self._weight(e.meas) for e in self._entries[i:])

    def add(self, meas: M, stamp: float, seq: int = 0) -> bool:
        """Fuse one measurement; False when rejected (too old or duplicate)."""
        key = (stamp, seq)
        if self._too_old(key):
            self.rejected_old += 1
            return False
        i = bisect.bisect_left(self._keys, key)
        if i < len(self._keys) and self._keys[i] == key:
            self.duplicates += 1
            return False
        before = self.state if i == len(self._entries) else self._entries[i].before
        self._entries.insert(i, _Entry(key=key, meas=meas, before=before))
        self._keys.insert(i, key)
        if i < len(self._entries) - 1:
            self.replays += 1
            self.refused += len(self._entries) - 1 - i
        state = before
        for entry in self._entries[i:]:  # roll back to `before`, then re-fuse in stamp order
            entry.before = state
            state = self._apply(state, entry.meas)
        self.state = state
        self.fused += 1
        self._newest = max(self._newest, stamp)
        self._prune()
        return True

    def _prune(self) -> None:
        # entries older than the window can no longer be re-fused before; drop them
        limit = self._newest - self._history_s
        n = bisect.bisect_left(self._keys, (limit, -1))
        if len(self._keys) - n > self._max_entries:
            n = len(self._keys) - self._max_entries
            self._floor = self._keys[n - 1]
        if n:
            del self._entries[:n]
            del self._keys[:n]

    def __len__(self) -> int:
        return len(self._entries)
