"""Everything a run published, kept in a deterministic order, and the trajectory hash."""

from __future__ import annotations

import hashlib
import logging
from collections.abc import Iterable
from typing import Literal, TypeVar

import numpy as np

from common.messages import Message, TruthState, replace
from common.runtime.model.seqwindow import DEFAULT_MAX_GAP, SeqWindow

M = TypeVar("M", bound=Message)

log = logging.getLogger("tidelink.record")

Refusal = Literal["wrong_source", "seq_jump", "conflict", "future"]
REFUSALS: tuple[Refusal, ...] = ("wrong_source", "seq_jump", "conflict", "future")
SEQ_LIMIT = 2**63  # the wire's bound on a seq (common/messages)


class Record:
    """Messages of a run by (service, stream), each list in seq order whatever arrival order.

    Anyone on the bus can put a message on any key, so a message is recorded only when it can
    be the stream's publisher's (refused and counted by reason in `rejected` otherwise):
    - wrong_source: its envelope `source` is not the service whose key it came on;
    - seq_jump: its seq is outside the stream's plausible window (SeqWindow): 0, or further
      ahead of the highest seq than the stream could publish in the whole mission;
    - conflict: a different message with a seq already recorded (the first one stays);
    - future: stamped after `latest_s`, the recorder's own mission time when it is given (a
      realtime run: no service's clock may be ahead of the launcher's, and the run's metrics
      must not run past its end).
    So one forged message cannot become a stream's `last` from far ahead.
    """

    def __init__(self, max_seq_gap: int = DEFAULT_MAX_GAP) -> None:
        self._streams: dict[tuple[str, str], dict[int, Message]] = {}
        self._windows: dict[tuple[str, str], SeqWindow] = {}
        self._last: dict[tuple[str, str], Message] = {}
        self._max_seq_gap = max_seq_gap
        self.count = 0
        self.rejected: dict[str, int] = dict.fromkeys(REFUSALS, 0)

    def add(
        self, service: str, stream: str, msg: Message, *, latest_s: float | None = None
    ) -> Refusal | None:
        """Record `msg`, seen on `service`'s `stream`; returns why it was refused, or None
        (recorded, or an exact repeat of a message already recorded)."""
        key = (service, stream)
        if msg.source != service:
            return self._refuse("wrong_source", key, msg)
        if latest_s is not None and msg.stamp > latest_s:
            return self._refuse("future", key, msg)
        seq = msg.seq
        window = self._windows.get(key)
        if window is None:
            window = self._windows[key] = SeqWindow(self._max_seq_gap)
        if not window.plausible(seq):
            return self._refuse("seq_jump", key, msg)
        bucket = self._streams.get(key)  # (not setdefault: no empty dict built per message)
        if bucket is None:
            bucket = self._streams[key] = {}
        old = bucket.get(seq)
        if old is not None:
            return None if old == msg else self._refuse("conflict", key, msg)
        bucket[seq] = msg
        window.take(seq)
        self.count += 1
        last = self._last.get(key)
        if last is None or seq > last.seq:
            self._last[key] = msg
        return None

    def _refuse(self, reason: Refusal, key: tuple[str, str], msg: Message) -> Refusal:
        self.rejected[reason] += 1
        n = self.rejected[reason]
        if n == 10 ** (len(str(n)) - 1):  # the 1st, 10th, 100th...: a flood logs a few lines
            log.warning(
                "refused a message on %s/%s (%s): %s from %r, seq %d (%d so far)",
                *key,
                reason,
                type(msg).__name__,
                msg.source,
                msg.seq,
                n,
            )
        return reason

    def last(self, service: str, stream: str) -> Message | None:
        """The message with the highest seq on a stream so far (None if none)."""
        return self._last.get((service, stream))

    def last_of(self, service: str, stream: str, kind: type[M]) -> M | None:
        """The message of type `kind` with the highest seq on a stream (None if none)."""
        for msg in reversed(self.stream(service, stream)):
            if isinstance(msg, kind):
                return msg
        return None

    def message(self, service: str, stream: str, seq: int) -> Message | None:
        """The message recorded with `seq` on a stream (None if none)."""
        return self._streams.get((service, stream), {}).get(seq)

    def stream(self, service: str, stream: str) -> list[Message]:
        bucket = self._streams.get((service, stream), {})
        return [bucket[k] for k in sorted(bucket)]

    def last_seq(self, service: str, stream: str) -> int:
        """Highest seq recorded on a stream (0 if none)."""
        last = self._last.get((service, stream))
        return 0 if last is None else last.seq

    def keys(self) -> list[tuple[str, str]]:
        return sorted(self._streams)


class Renumbering:
    """Keeps the lives of a restarted service apart in a record.

    A restarted service numbers its messages from 1 again, and Record.add dedupes by seq: its
    new messages would be taken for repeats. Once it rejoins, each of its streams whose next
    message starts its numbering over (a seq not above the last one before) is offset by the
    highest seq recorded there so far; a stream that goes on numbering (the same process,
    back after its session was cut, e.g. by a router restart) is not. The realtime driver
    records a run this way, and a recording is replayed into a Record the same way
    (services/recording).
    """

    def __init__(self, record: Record) -> None:
        self.record = record
        self.offset: dict[tuple[str, str], int] = {}
        self._rejoined: set[tuple[str, str]] = set()  # streams whose next message is judged

    def rejoined(self, service: str) -> None:
        """`service` came back (its liveliness token reappeared): a stream of it whose next
        message numbers from the start again is renumbered from there on."""
        self._rejoined.update(key for key in self.record.keys() if key[0] == service)

    def _judge(self, key: tuple[str, str], seq: int) -> None:
        """The first message of a rejoined service's stream: a new process's numbering, or the
        old one's going on?"""
        self._rejoined.discard(key)
        last = self.record.last_seq(*key)
        if seq <= last - self.offset.get(key, 0):
            self.offset[key] = last

    def add(
        self, service: str, stream: str, msg: Message, *, latest_s: float | None = None
    ) -> Message | None:
        """Record `msg` with its seq offset; returns it as recorded, or None if refused
        (`latest_s`: Record.add's)."""
        if (service, stream) in self._rejoined:
            self._judge((service, stream), msg.seq)
        offset = self.offset.get((service, stream), 0)
        # a seq the offset would push past the wire's limit is left as it is: far beyond
        # any plausible seq, the record refuses it (as seq_jump)
        if offset and msg.seq < SEQ_LIMIT - offset:
            msg = replace(msg, seq=msg.seq + offset)
        return None if self.record.add(service, stream, msg, latest_s=latest_s) else msg


def trajectory_sha256(truth: Iterable[TruthState]) -> str:
    """SHA-256 of the true trajectory log: (t, x, y, theta, v, w) rows as little-endian float64."""
    rows = [(m.stamp, m.x, m.y, m.theta, m.v, m.w) for m in truth]
    arr = np.asarray(rows, dtype="<f8").reshape(-1, 6)
    return hashlib.sha256(arr.tobytes()).hexdigest()
