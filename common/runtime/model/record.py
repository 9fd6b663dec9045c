"""Everything a run published, kept in a deterministic order, and the trajectory hash."""

from __future__ import annotations

import hashlib
from collections.abc import Iterable

import numpy as np

from common.messages import Message, TruthState, replace


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


class Renumbering:
    """Keeps the lives of a restarted service apart in a record.

    A restarted service numbers its messages from 1 again, and Record.add dedupes by seq: its
    new messages would be taken for repeats. From the moment it rejoins, each of its streams
    is offset by the highest seq recorded there so far. The realtime driver records a run
    this way, and a recording is replayed into a Record the same way (services/recording).
    """

    def __init__(self, record: Record) -> None:
        self.record = record
        self.offset: dict[tuple[str, str], int] = {}

    def rejoined(self, service: str) -> None:
        """`service` came back (its liveliness token reappeared): renumber what follows."""
        for s, stream in self.record.keys():
            if s == service:
                self.offset[(s, stream)] = self.record.last_seq(s, stream)

    def add(self, service: str, stream: str, msg: Message) -> Message:
        """Record `msg` with its seq offset; returns it as recorded."""
        offset = self.offset.get((service, stream), 0)
        if offset:
            msg = replace(msg, seq=msg.seq + offset)
        self.record.add(service, stream, msg)
        return msg


def trajectory_sha256(truth: Iterable[TruthState]) -> str:
    """SHA-256 of the true trajectory log: (t, x, y, theta, v, w) rows as little-endian float64."""
    rows = [(m.stamp, m.x, m.y, m.theta, m.v, m.w) for m in truth]
    arr = np.asarray(rows, dtype="<f8").reshape(-1, 6)
    return hashlib.sha256(arr.tobytes()).hexdigest()
