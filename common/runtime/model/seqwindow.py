"""Per-stream sequence sanity: which seqs of a stream are in, and which a publisher can send.

A runtime numbers each stream's messages 1, 2, 3, ... (a restarted publisher is renumbered to
carry on), so a seq of 0, or one further beyond the highest seen than the stream could have
published in the whole mission, cannot be the publisher's: whoever put it on the bus, it is
refused and it never moves the window, so the publisher's next messages are still taken.
"""

from __future__ import annotations

import math

from common.runtime.model.dataflow import Dataflow

# Headroom of the bound below: cores may emit more than one message on a stream in a step,
# and event-driven services step on deliveries rather than on a period.
GAP_FACTOR = 4
GAP_SLACK = 1024
# The bound when no service has a period (an event-driven mission): still far below the
# 2**62 a forged message may carry, so a renumbered seq never nears the wire's 2**63 limit.
DEFAULT_MAX_GAP = 2**20


def max_seq_gap(flow: Dataflow, max_time_s: float) -> int:
    """How far past the highest seq a stream's next message may be: GAP_FACTOR times the steps
    of the mission's fastest periodic service in max_time_s, plus GAP_SLACK (default mission:
    4 x 200 s / 0.05 s + 1024 = 17024)."""
    periods = [s.period_s for s in flow.services.values() if s.period_s is not None]
    if not periods or not math.isfinite(max_time_s):
        return DEFAULT_MAX_GAP
    return min(DEFAULT_MAX_GAP, math.ceil(GAP_FACTOR * max_time_s / min(periods)) + GAP_SLACK)


class SeqWindow:
    """The seqs of one stream seen so far: the complete prefix 1..`prefix`, those beyond it,
    the highest; and whether a new seq is one the stream's publisher could have sent."""

    def __init__(self, max_gap: int = DEFAULT_MAX_GAP) -> None:
        self.max_gap = max_gap
        self.prefix = 0  # 1..prefix all seen: what a lockstep runtime waits for
        self.highest = 0
        self._ahead: set[int] = set()  # seen, beyond a hole in the prefix

    def plausible(self, seq: int) -> bool:
        """Whether `seq` can be the publisher's: in [1, highest + max_gap]."""
        return 0 < seq <= self.highest + self.max_gap

    def seen(self, seq: int) -> bool:
        return seq <= self.prefix or seq in self._ahead

    def take(self, seq: int) -> None:
        """Count a plausible `seq` as seen (a repeat changes nothing)."""
        if self.seen(seq):
            return
        if seq > self.highest:
            self.highest = seq
        if seq != self.prefix + 1:
            self._ahead.add(seq)
            return
        self.prefix = seq
        while self._ahead and self.prefix + 1 in self._ahead:  # (none, but after a hole)
            self.prefix += 1
            self._ahead.discard(self.prefix)
