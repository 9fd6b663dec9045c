"""Everything a run published, kept in a deterministic order, and the trajectory hash."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable

import numpy as np

from common.messages import Message, TruthState


class Record:
    """Messages of a run by (service, stream), each list in seq order whatever arrival order."""

    def __init__(self) -> None:
        self._streams: dict[tuple[str, str], dict[int, Message]] = {}
        self._last: dict[tuple[str, str], Message] = {}
        self.count = 0

    def add(self, service: str, stream: str, msg: Message) -> None:
        bucket = self._streams.setdefault((service, stream), {})
        if msg.seq not in bucket:
            bucket[msg.seq] = msg
            self.count += 1
            last = self._last.get((service, stream))
            if last is None or msg.seq > last.seq:
                self._last[(service, stream)] = msg

    def last(self, service: str, stream: str) -> Message | None:
        """The message with the highest seq on a stream so far (None if none)."""
        return self._last.get((service, stream))

    def stream(self, service: str, stream: str) -> list[Message]:
        bucket = self._streams.get((service, stream), {})
        return [bucket[k] for k in sorted(bucket)]

    def last_seq(self, service: str, stream: str) -> int:
        """Highest seq seen on a stream (0 if none)."""
        bucket = self._streams.get((service, stream))
        return max(bucket) if bucket else 0

    def missing(self, watermarks: dict[str, int]) -> list[str]:
        """The 'service/stream' keys whose messages up to the watermark are not all here."""
        out = []
        for key, seq in watermarks.items():
            service, _, stream = key.partition("/")
            if seq and len(self._streams.get((service, stream), ())) < seq:
                out.append(key)
        return out

    def keys(self) -> list[tuple[str, str]]:
        return sorted(self._streams)


def trajectory_sha256(truth: Iterable[TruthState]) -> str:
    """SHA-256 of the true trajectory log: (t, x, y, theta, v, w) rows as little-endian float64."""
    rows = [(m.stamp, m.x, m.y, m.theta, m.v, m.w) for m in truth]
    arr = np.asarray(rows, dtype="<f8").reshape(-1, 6)
    return hashlib.sha256(arr.tobytes()).hexdigest()
