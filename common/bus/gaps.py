"""Frames a watcher lost, counted from the gaps in each stream's seq numbers (recorders,
monitors and Foxglove bridges count their own losses with it).

A run's services number each stream's messages 1, 2, 3, ... and the watch tap copies them
with congestion DROP: a watcher that cannot keep up loses copies, and the gaps show how many.
A seq lower than the last one is a restarted service numbering from 1 again: the frames
before it in its new life are lost too. Frames before the first one seen are not counted:
a watcher that joins late never asked for them.
"""

from __future__ import annotations

from collections import Counter


class SeqGaps:
    """Counts lost frames per stream (keys are whatever the caller names streams by)."""

    def __init__(self) -> None:
        self._last: dict[str, int] = {}
        self.first: dict[str, int] = {}  # the first seq seen per stream
        self.lost: Counter[str] = Counter()
        self.restarts: Counter[str] = Counter()

    def see(self, stream: str, seq: int) -> None:
        last = self._last.get(stream)
        if last is None:
            self.first[stream] = seq
        elif seq > last + 1:
            self.lost[stream] += seq - last - 1
        elif seq == last:
            return  # the same frame twice (e.g. a late-join query's answer and its copy)
        elif seq < last:
            self.restarts[stream] += 1
            self.lost[stream] += max(0, seq - 1)
        self._last[stream] = seq

    def behind(self, stream: str, seq: int) -> None:
        """The run's newest frame of `stream` (asked for when a watcher stops): every frame up
        to it that the watcher never got is lost too, it included."""
        last = self._last.get(stream)
        if last is not None and seq > last:
            self.lost[stream] += seq - last
            self._last[stream] = seq

    @property
    def total(self) -> int:
        return sum(self.lost.values())
