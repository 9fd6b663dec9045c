"""Host one core: envelope and seq numbers, the link model on its outputs, modelled deliveries.

This is the part every runtime shares, so inproc and lockstep behave identically:
- a tick at virtual time T (integer microseconds) hands over deliveries due at or before T
  that were sent in an earlier tick (a message is never delivered in the tick it was sent),
  in the fixed order (delivery time, source, stream, seq, copy);
- deliveries to `wake` inputs go to the core at once; the others wait in a ready buffer until
  the core's next step, where the input's queue policy applies (NEWEST keeps the last one);
- each output gets (source, seq, sent) and, per receiving service, the link model's delivery
  times, decided on the sending side from (seed, link, seq) so no arrival order matters.
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

from common.config.network import link_name
from common.messages import LinkCounters, LinkStats, MeasuredDelay, Message, encode
from common.netmodel import NetworkModel
from common.netmodel.stats import LinkStatsAccumulator
from common.runtime.model.core import Delivery, Emit, QueuePolicy, ServiceCore
from common.runtime.model.dataflow import Dataflow, Input

STATS_STREAM = "stats"
NEVER = 2**62


def to_us(t: float) -> int:
    return round(t * 1e6)


@dataclass(frozen=True, slots=True)
class Outgoing:
    """One published message: its bytes and modelled delivery times (us) per receiver.

    Only the bytes travel: receivers (and the inproc runtime) decode them, exactly as a
    Zenoh subscriber would.
    """

    stream: str
    data: bytes
    schedule: dict[str, tuple[int, ...]]


class Host:
    """Runs one core inside any runtime (see the module docstring for the rules)."""

    def __init__(
        self,
        flow: Dataflow,
        name: str,
        core: ServiceCore,
        net: NetworkModel,
        *,
        stats_period_s: float = 1.0,
    ) -> None:
        service = flow.service(name)
        self.core = core
        self.name = name
        self.flow = flow
        self.net = net
        # an event-driven service (no period) never steps on its own
        self.period_us = NEVER if service.period_s is None else to_us(service.period_s)
        self.next_step_us = NEVER if service.period_s is None else to_us(service.offset_s)
        self.stats_period_us = to_us(stats_period_s)
        self.next_stats_us = self.stats_period_us
        self._inputs: dict[tuple[str, str], Input] = {
            (i.source, i.stream): i for i in service.inputs
        }
        self._seq: dict[str, int] = {o.stream: 0 for o in service.outputs}
        self._seq[STATS_STREAM] = 0
        # (deliver_us, source, stream, seq, copy, sent_tick, msg)
        self._pending: list[tuple[int, str, str, int, int, int, Message]] = []
        self._ready: list[Delivery] = []
        # delays measured on incoming links (hand-over time - sent), by link name
        self._measured: dict[tuple[str, str], LinkStatsAccumulator] = {}
        self.delivered = 0
        self.superseded = 0  # deliveries a NEWEST input dropped for a newer one

    @property
    def inputs(self) -> tuple[Input, ...]:
        """The service's declared inputs."""
        return tuple(self._inputs.values())

    @property
    def streams(self) -> tuple[str, ...]:
        """Every stream this host publishes on: its declared outputs, then stats."""
        return tuple(self._seq)

    # -- receiving ---------------------------------------------------------------------------
    def accept(
        self, msg: Message, source: str, stream: str, times_us: tuple[int, ...], sent_tick: int
    ) -> None:
        """Queue a message sent to this host, with its modelled delivery times."""
        if (source, stream) not in self._inputs:
            return
        for copy, t in enumerate(times_us):
            heapq.heappush(self._pending, (t, source, stream, msg.seq, copy, sent_tick, msg))

    def next_event_us(self) -> int:
        """The next time this host needs a tick: its next step or a due wake delivery."""
        nxt = self.next_step_us
        for t, src, stream, *_ in self._pending:
            if t < nxt and self._inputs[(src, stream)].wake:
                nxt = t
        return nxt

    # -- one tick ----------------------------------------------------------------------------
    def run_tick(self, tick: int, t_us: int) -> list[Outgoing]:
        """Hand over due deliveries, step if due, and publish what the core emitted."""
        emits: list[Emit] = []
        later = []
        while self._pending and self._pending[0][0] <= t_us:
            item = heapq.heappop(self._pending)
            if item[5] >= tick:  # sent in this tick: never delivered in the tick it was sent
                later.append(item)
                continue
            d_us, src, stream, _seq, copy, _tick, msg = item
            d = Delivery(source=src, stream=stream, msg=msg, t=d_us / 1e6)
            self.delivered += 1
            if copy == 0:
                acc = self._measured.get((src, stream))
                if acc is None:
                    acc = self._measured[(src, stream)] = LinkStatsAccumulator()
                acc.record(msg.sent, (d.t,), None)
            if self._inputs[(src, stream)].wake:
                emits.extend(self.core.deliver(d))
            else:
                self._ready.append(d)
        for item in later:
            heapq.heappush(self._pending, item)
        if self.next_step_us <= t_us:
            t = t_us / 1e6
            for d in self._policy(self._ready):
                emits.extend(self.core.deliver(d))
            self._ready = []
            emits.extend(self.core.step(t))
            self.next_step_us += self.period_us
        out = [self._publish(e.stream, e.msg, tick, t_us) for e in emits]
        if t_us >= self.next_stats_us:
            out.append(self.publish_stats(tick, t_us))
            while self.next_stats_us <= t_us:
                self.next_stats_us += self.stats_period_us
        return out

    def _policy(self, ready: list[Delivery]) -> list[Delivery]:
        newest: dict[tuple[str, str], int] = {}
        for i, d in enumerate(ready):
            if self._inputs[(d.source, d.stream)].policy is QueuePolicy.NEWEST:
                newest[(d.source, d.stream)] = i
        if not newest:
            return ready
        kept = [
            d
            for i, d in enumerate(ready)
            if self._inputs[(d.source, d.stream)].policy is not QueuePolicy.NEWEST
            or newest[(d.source, d.stream)] == i
        ]
        self.superseded += len(ready) - len(kept)
        return kept

    # -- the clock, for runtimes that join or fall behind it (realtime) ----------------------
    def join_clock(self, t_us: int) -> bool:
        """Start stepping at the first period boundary at or after t_us (a late joiner does
        not replay every period since 0); True if the schedule moved."""
        if t_us <= self.next_step_us or self.next_step_us >= NEVER:
            return False
        self.next_step_us += -(-(t_us - self.next_step_us) // self.period_us) * self.period_us
        return True

    def skip_missed(self, now_us: int) -> int:
        """Skip whole periods already past (a step that fell behind); returns how many."""
        if self.next_step_us >= NEVER:
            return 0
        behind = max(0, (now_us - self.next_step_us) // self.period_us)
        self.next_step_us += behind * self.period_us
        return behind

    # -- publishing ---------------------------------------------------------------------------
    def publish_stats(self, tick: int, t_us: int) -> Outgoing:
        """The link statistics of this host at t_us, as an outgoing message on 'stats'."""
        return self._publish(STATS_STREAM, self.link_stats(t_us / 1e6), tick, t_us)

    def _publish(self, stream: str, msg: Message, tick: int, t_us: int) -> Outgoing:
        if stream not in self._seq:
            raise ValueError(f"{self.name}: emitted on undeclared stream {stream!r}")
        self._seq[stream] += 1
        seq = self._seq[stream]
        t = t_us / 1e6
        data = encode(msg, source=self.name, seq=seq, sent=t)
        schedule: dict[str, tuple[int, ...]] = {}
        for receiver, _spec in self.flow.receivers.get((self.name, stream), ()):
            dec = self.net.decide(self.name, stream, receiver, seq, t, len(data))
            schedule[receiver] = tuple(to_us(x) for x in dec.delivered_at)
        return Outgoing(stream, data, schedule)

    def wake_deliveries_us(self, out: list[Outgoing]) -> dict[str, int]:
        """Earliest delivery to a wake input per receiver, among messages just sent: what the
        lockstep coordinator must know before the receivers themselves have seen them."""
        best: dict[str, int] = {}
        for o in out:
            for receiver, spec in self.flow.receivers.get((self.name, o.stream), ()):
                times = o.schedule.get(receiver)
                if spec.wake and times:
                    best[receiver] = min(best.get(receiver, NEVER), times[0])
        return best

    def published(self) -> dict[str, int]:
        """Last seq published per output stream."""
        return dict(self._seq)

    def link_stats(self, t: float) -> LinkStats:
        """Counters of every outgoing link so far, as the wire message."""
        links = tuple(
            LinkCounters(
                link=name,
                sent=s.sent,
                delivered=s.delivered,
                dropped_loss=s.dropped_loss,
                dropped_outage=s.dropped_outage,
                dropped_queue=s.dropped_queue,
                duplicated=s.duplicated,
                delay_p50=s.delay_p50_s,
                delay_p95=s.delay_p95_s,
                delay_p99=s.delay_p99_s,
            )
            for name, s in self.net.snapshots().items()
        )
        measured = tuple(
            MeasuredDelay(
                link=link_name(src, stream, self.name),
                delivered=m.delivered,
                delay_p50=m.delay_p50_s,
                delay_p95=m.delay_p95_s,
                delay_max=m.delay_max_s,
            )
            for (src, stream), m in sorted((k, a.snapshot()) for k, a in self._measured.items())
        )
        return LinkStats(stamp=t, links=links, measured=measured)
