"""One link's model: decides, per sent message, when (and how often) it is delivered, or why not.

Pipeline for message ``seq`` sent at ``t`` (all draws from ``CounterRng(seed, link)`` at ``seq``):
1. outage: the link is down at ``t`` -> dropped ("outage"); nothing is transmitted;
2. Gilbert-Elliott state step (every message not dropped in 1, so the chain never stalls);
3. bandwidth queue: tail-dropped ("queue"), else it leaves the sender at ``t_tx >= t``;
4. loss on the wire ("loss"): Bernoulli or Gilbert-Elliott;
5. delay: each copy arrives at ``t_tx + delay``; with probability duplicate_p a second copy
   with its own delay draw (duplicates happen downstream and take no bandwidth);
6. FIFO (if set): a copy never arrives before the previous delivery on the link;
7. outage: a copy in flight when a window opens is dropped; if no copy survives -> "outage".
Delivery times are rounded to whole microseconds so runtimes can keep integer-us clocks.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Literal, NamedTuple

from common.config.network import LinkProfile, Outage, parse_link
from common.netmodel.delay import DelaySampler
from common.netmodel.loss import make_loss
from common.netmodel.outage import OutageSchedule
from common.netmodel.queue import BandwidthQueue
from common.netmodel.rng import (
    N_DRAWS,
    U_DELAY,
    U_DELAY_DUP,
    U_DUPLICATE,
    U_GE_STATE,
    U_LOSS,
    CounterRng,
    unit,
)
from common.netmodel.stats import LinkStatsAccumulator

DropCause = Literal["loss", "outage", "queue"]


class Decision(NamedTuple):
    """The model's verdict on one message: delivery times (empty if dropped) or a drop cause.

    An immutable named tuple rather than a frozen dataclass: one is made for every message a
    link decides, and a frozen dataclass's __init__ (one object.__setattr__ a field) cost
    twice as much.
    """

    seq: int
    delivered_at: tuple[float, ...]  # 0 entries if dropped, 2 if duplicated (in arrival order)
    drop_cause: DropCause | None = None  # set exactly when delivered_at is empty

    @property
    def dropped(self) -> bool:
        """Whether no copy of the message is delivered."""
        return not self.delivered_at


_NO_WORDS = (0,) * N_DRAWS


def us(t: float) -> float:
    """t rounded to whole microseconds (runtimes keep integer-us clocks)."""
    return round(t * 1e6) / 1e6


def check_send(
    seq: int, send_time: float, size_bytes: int, last_seq: int, last_send: float
) -> None:
    """The contract of every link model's ``decide``: strictly increasing seq below 2**64,
    finite non-decreasing send times, a size >= 0 (ValueError naming the argument)."""
    if seq <= last_seq or seq >= 2**64:
        raise ValueError(f"seq: {seq!r} is invalid, expected > {last_seq} and < 2**64")
    if not (send_time >= last_send and math.isfinite(send_time)):
        raise ValueError(
            f"send_time: {send_time!r} is invalid, expected finite and >= {last_send!r}"
        )
    if size_bytes < 0:
        raise ValueError(f"size_bytes: {size_bytes!r} is invalid, expected >= 0")


class LinkModel:
    """The stateful model of one link; a deterministic function of (seed, link, sent sequence).

    State: the Gilbert-Elliott channel state, the queue and the last FIFO delivery time. Call
    ``decide`` once per sent message, in send order (strictly increasing ``seq``,
    non-decreasing ``send_time``).
    """

    def __init__(
        self,
        profile: LinkProfile,
        *,
        seed: int,
        link: str,
        outages: Iterable[Outage] = (),
        trace: Sequence[float] | None = None,
    ) -> None:
        parse_link(link)  # validates the name
        self.profile = profile
        self.link = link
        self.stats = LinkStatsAccumulator()
        self._rng = CounterRng(seed=seed, link=link)
        self._delay = DelaySampler(profile, trace)
        self._loss = make_loss(profile)
        self._queue = BandwidthQueue(
            bandwidth_bps=profile.bandwidth_bps, queue_len=profile.queue_len
        )
        self._outages = OutageSchedule(link, outages)
        self._has_outages = bool(self._outages.windows)
        self._dup_p = profile.duplicate_p
        self._fifo = profile.fifo
        # an ideal, constant-delay link draws nothing: skip the hash (same decisions either way)
        self._random = (
            profile.loss != "none" or profile.jitter != "none" or profile.duplicate_p > 0.0
        )
        # nothing but a constant delay (every local link; the ideal default): the delivery is
        # the send time plus it, nothing drawn, queued or cut (same verdicts, a third the time;
        # a fleet's vehicle decides its truth on a link to every other vehicle's sensor)
        self._fixed_delay = (
            profile.delay_s
            if not (self._random or self._has_outages or profile.trace_file or trace)
            and self._queue.unlimited
            else None
        )
        self._last_delivery = -math.inf
        self._last_seq = -1
        self._last_send = -math.inf

    def decide(self, seq: int, send_time: float, size_bytes: int) -> Decision:
        """Decide the delivery of message ``seq`` (``size_bytes`` encoded) sent at ``send_time``."""
        check_send(seq, send_time, size_bytes, self._last_seq, self._last_send)
        self._last_seq = seq
        self._last_send = send_time
        decision = self._decide(seq, send_time, size_bytes)
        self.stats.record(send_time, decision.delivered_at, decision.drop_cause, size_bytes)
        return decision

    def _decide(self, seq: int, t: float, size_bytes: int) -> Decision:
        if self._fixed_delay is not None:
            # in send order, so never before the previous delivery: FIFO holds by itself
            self._last_delivery = a = us(t + self._fixed_delay)
            return Decision(seq=seq, delivered_at=(a,))
        if self._has_outages and self._outages.down_at(t):
            return Decision(seq=seq, delivered_at=(), drop_cause="outage")
        # raw words; only the uniforms this profile uses are converted (the costly part)
        w = self._rng.words(seq) if self._random else _NO_WORDS
        lost = self._loss.lost(unit(w[U_GE_STATE]), unit(w[U_LOSS]))
        t_tx = self._queue.offer(t, size_bytes)
        if t_tx is None:
            return Decision(seq=seq, delivered_at=(), drop_cause="queue")
        if lost:
            return Decision(seq=seq, delivered_at=(), drop_cause="loss")
        arrivals = [us(t_tx + self._delay.sample(unit(w[U_DELAY]), seq, 0))]
        if self._dup_p > 0.0 and unit(w[U_DUPLICATE]) < self._dup_p:
            arrivals.append(us(t_tx + self._delay.sample(unit(w[U_DELAY_DUP]), seq, 1)))
            arrivals.sort()
        delivered: list[float] = []
        for a in arrivals:
            if self._fifo and a < self._last_delivery:
                a = self._last_delivery  # FIFO: delivery = max(own, previous delivery on the link)
            if self._has_outages and self._outages.cuts(t, a):
                continue
            delivered.append(a)
            if a > self._last_delivery:
                self._last_delivery = a
        if not delivered:
            return Decision(seq=seq, delivered_at=(), drop_cause="outage")
        return Decision(seq=seq, delivered_at=tuple(delivered))
