"""One half-duplex acoustic modem: a single frame on the channel at a time, the rest queued."""

from __future__ import annotations

from common.config.acoustic import AcousticMedium
from common.netmodel.queue import BandwidthQueue


class Modem:
    """The transmit side of one modem: frames leave one after another at the bit rate
    (BandwidthQueue: FIFO, at most ``queue_frames`` waiting, tail drop, counted in
    ``dropped``); with ``one_per_stream`` a stream whose previous frame is still waiting
    loses the new message instead (what a modem driver does with state-like data: the
    channel carries recent samples, not a backlog). The medium is a broadcast: the same
    message offered again (for a second receiver on the far node) is the same frame, so it
    returns that frame's start again.
    """

    def __init__(self, medium: AcousticMedium) -> None:
        self.medium = medium
        # bytes already include the header: one byte costs 8 / bit_rate seconds
        self._queue = BandwidthQueue(
            bandwidth_bps=medium.bit_rate_bps, queue_len=medium.queue_frames
        )
        self._last: tuple[tuple[str, int], float | None] | None = None
        self._waiting: dict[str, float] = {}  # per stream, the start of its newest frame
        self.frames = 0
        self.dropped = 0

    def offer(self, key: tuple[str, int], t: float, size_bytes: int) -> float | None:
        """Start time on the channel of message `key` (stream, seq) of size_bytes offered at
        t, or None when the queue is full (the frame is dropped)."""
        if self._last is not None and self._last[0] == key:
            return self._last[1]
        stream = key[0]
        waiting = self._waiting.get(stream)
        if self.medium.one_per_stream and waiting is not None and waiting > t:
            start = None  # this stream's previous frame has not gone out yet: keep that one
        else:
            end = self._queue.offer(t, size_bytes + self.medium.header_bytes)
            start = None if end is None else end - self.medium.frame_s(size_bytes)
            if start is not None:
                self._waiting[stream] = start
        if start is None:
            self.dropped += 1
        else:
            self.frames += 1
        self._last = (key, start)
        return start
