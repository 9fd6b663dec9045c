"""Bandwidth of a link: a single transmitter with a bounded FIFO queue and tail drop.

A message of ``size_bytes`` occupies the transmitter for ``8 * size_bytes / bandwidth_bps``
seconds. Messages that arrive while it is busy wait in the queue; one that arrives when
``queue_len`` messages are already waiting (accepted, transmission not yet started) is dropped.
"""

from __future__ import annotations

from collections import deque


class BandwidthQueue:
    """Serialisation and tail drop for one link; arrivals must come in non-decreasing time."""

    def __init__(self, *, bandwidth_bps: float, queue_len: int) -> None:
        self._s_per_byte = 8.0 / bandwidth_bps if bandwidth_bps > 0.0 else 0.0
        self._queue_len = queue_len
        self._busy_until = 0.0  # when the transmitter finishes everything accepted so far
        self._starts: deque[float] = deque()  # transmission start times not yet reached

    @property
    def unlimited(self) -> bool:
        """True when the link has no bandwidth limit (transmission takes no time)."""
        return self._s_per_byte == 0.0

    def offer(self, t: float, size_bytes: int) -> float | None:
        """Time the message has left the sender (fully serialised), or None if tail-dropped."""
        if self._s_per_byte == 0.0:
            return t
        starts = self._starts
        while starts and starts[0] <= t:  # these are in transmission or already sent
            starts.popleft()
        if len(starts) >= self._queue_len:
            return None
        start = self._busy_until if self._busy_until > t else t
        if start > t:
            starts.append(start)  # it waits until the transmitter frees up
        self._busy_until = start + size_bytes * self._s_per_byte
        return self._busy_until
