"""Host one core: envelope and seq numbers, the link model on its outputs, modelled deliveries.

This is the part every runtime shares, so inproc and lockstep behave identically:
- a tick at virtual time T (integer microseconds) hands over deliveries due at or before T
  that were sent in an earlier tick (a message is never delivered in the tick it was sent),
  in the fixed order (delivery time, source, stream, seq, copy);
- deliveries to `wake` inputs go to the core at once; the others wait in a ready buffer until
  the core's next step, where the input's queue policy applies (NEWEST keeps the last one);
- each input holds at most its declared `max_queued` deliveries (in flight and ready): past
  that the one due first is dropped and counted, so a flood of messages costs bounded memory
  and bounded work per step, and the newest samples survive;
- each output gets (source, seq, sent) and, per receiving service, the link model's delivery
  times, decided on the sending side from (seed, link, seq) so no arrival order matters.
"""

from __future__ import annotations

import heapq
import itertools
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import cast

from common.config.network import link_name
from common.messages import (
    LINK_COUNTS,
    LinkCounters,
    LinkStats,
    MeasuredDelay,
    Message,
    TruthState,
    WireError,
    decode,
    encode,
)
from common.netmodel import NetworkModel
from common.netmodel.stats import DurationHistogram
from common.runtime.model.core import (
    CountsForStats,
    Delivery,
    Emit,
    JudgesInputs,
    Prepares,
    QueuePolicy,
    RestartsFilters,
    Resumes,
    ServiceCore,
)
from common.runtime.model.dataflow import Dataflow, Input
from common.runtime.model.drops import InputDrops

STATS_STREAM = "stats"
NEVER = 2**62

# (deliver_us, source, stream, seq, copy, sent_tick, arrival, msg): ordered by the first five;
# `arrival` (a counter) only separates exact repeats, so a message is never compared
Pending = tuple[int, str, str, int, int, int, int, Message]


def to_us(t: float) -> int:
    return round(t * 1e6)


@dataclass(frozen=True, slots=True)
class Outgoing:
    """One published message: its bytes and modelled delivery times (us) per receiver.

    Only the bytes travel: receivers (and the inproc runtime) decode them, exactly as a
    Zenoh subscriber would.
    """

    stream: str
    seq: int  # the message's, as in its envelope
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
        # per stream published, who receives it (looked up for every message published)
        self._receivers = {s: flow.receivers.get((name, s), ()) for s in self._seq}
        # per input, a heap of deliveries not yet due (or sent in the current tick)
        self._pending: dict[tuple[str, str], list[Pending]] = {k: [] for k in self._inputs}
        self._wake = tuple(k for k, i in self._inputs.items() if i.wake)
        self._arrival = itertools.count()
        self._ready: list[Delivery] = []
        # delays measured on incoming links (hand-over time - sent), by input: a histogram
        # (its count is the deliveries measured), not a whole link's counters, as it is
        # updated at every delivery and the statistics carry only these (MeasuredDelay)
        self._measured: dict[tuple[str, str], DurationHistogram] = {}
        self.delivered = 0
        self.superseded = 0  # deliveries a NEWEST input dropped for a newer one
        # the core prepares its next step once a step's outputs are out (core.Prepares); the
        # time of the next step, set by a tick that stepped, until `prepare` is called
        self._prepares = isinstance(core, Prepares)
        # the other optional protocols, told once: isinstance on a runtime_checkable Protocol
        # costs ~10 us, and statistics are published every second
        self._judges = isinstance(core, JudgesInputs)
        self._restarts = isinstance(core, RestartsFilters)
        self._counts = isinstance(core, CountsForStats)
        self._prepare_for: float | None = None
        self.drops = InputDrops(name)
        self._now_us = 0  # the last tick's time (drops are logged on the mission clock)
        # counters of the runtime around this host, carried in its statistics beside the
        # core's (a realtime service's loop times, loop_times.py)
        self.runtime_counters: Callable[[], Mapping[str, int]] = dict

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
        """Queue a message sent to this host, with its modelled delivery times; an input
        already holding max_queued deliveries drops the one due first (maybe this one)."""
        key = (source, stream)
        inp = self._inputs.get(key)
        if inp is None:
            return
        if not isinstance(msg, inp.msg_type):  # well-formed, but not what this input carries
            self.count_dropped(source, stream, 1, "wrong type", type(msg).__name__)
            return
        heap = self._pending[key]
        for copy, t in enumerate(times_us):
            item = (t, source, stream, msg.seq, copy, sent_tick, next(self._arrival), msg)
            if len(heap) < inp.max_queued:
                heapq.heappush(heap, item)
            else:
                heapq.heappushpop(heap, item)
                self.count_dropped(source, stream, 1, "queue full")

    def count_dropped(self, source: str, stream: str, n: int, why: str, detail: str = "") -> None:
        """Count n messages for an input lost before its core saw them (here, or by the
        runtime in front of this host: no routing, a full inbox); see InputDrops."""
        if (source, stream) in self._inputs and n > 0:
            self.drops.count(source, stream, n, why, self._now_us / 1e6, detail)

    @property
    def dropped(self) -> dict[tuple[str, str], int]:
        """Messages dropped per input (source, stream) before the core saw them."""
        return dict(self.drops.counts)

    def next_event_us(self) -> int:
        """The next time this host needs a tick: its next step or a due wake delivery."""
        nxt = self.next_step_us
        for key in self._wake:
            heap = self._pending[key]
            if heap and heap[0][0] < nxt:
                nxt = heap[0][0]
        return nxt

    # -- one tick ----------------------------------------------------------------------------
    def run_tick(self, tick: int, t_us: int) -> list[Outgoing]:
        """Hand over due deliveries, step if due, and publish what the core emitted."""
        emits: list[Emit] = []
        self._now_us = t_us
        due: list[Pending] = []
        for heap in self._pending.values():
            while heap and heap[0][0] <= t_us:
                due.append(heapq.heappop(heap))
        due.sort()  # the fixed order: (delivery time, source, stream, seq, copy)
        later = []
        for item in due:
            if item[5] >= tick:  # sent in this tick: never delivered in the tick it was sent
                later.append(item)
                continue
            d_us, src, stream, _seq, copy, _tick, _arrival, msg = item
            key = (src, stream)
            inp = self._inputs[key]
            if isinstance(msg, TruthState):  # where the vehicle is: acoustic ranges
                self.net.observe_vehicle(msg.x, msg.y)
                if inp.tap:
                    continue
            t = d_us / 1e6
            d = Delivery(source=src, stream=stream, msg=msg, t=t)
            self.delivered += 1
            if copy == 0:
                hist = self._measured.get(key)
                if hist is None:
                    hist = self._measured[key] = DurationHistogram()
                delay = t - msg.sent  # >= 0 but across clocks (realtime): clipped at 0
                hist.record(delay if delay > 0.0 else 0.0)
            if inp.wake:
                emits.extend(self.core.deliver(d))
            else:
                self._ready.append(d)
        for item in later:
            heapq.heappush(self._pending[(item[1], item[2])], item)
        if self.next_step_us <= t_us:
            t = t_us / 1e6
            for d in self._policy(self._ready):
                emits.extend(self.core.deliver(d))
            self._ready = []
            emits.extend(self.core.step(t))
            self.next_step_us += self.period_us
            if self._prepares:
                self._prepare_for = self.next_step_us / 1e6
        out = [self._publish(e.stream, e.msg, tick, t_us) for e in emits]
        if t_us >= self.next_stats_us:
            out.append(self.publish_stats(tick, t_us))
            while self.next_stats_us <= t_us:
                self.next_stats_us += self.stats_period_us
        return out

    @property
    def prepare_pending(self) -> bool:
        """Whether the core may prepare its next step now (a step ran since it last did)."""
        return self._prepare_for is not None

    def prepare(self) -> bool:
        """After a tick that stepped, once its outputs are published: let the core prepare
        its next step (core.Prepares). True if it did."""
        t_next, self._prepare_for = self._prepare_for, None
        if t_next is None:
            return False
        assert self._prepares  # (set only by a core that Prepares)
        cast(Prepares, self.core).prepare(t_next)
        return True

    def _policy(self, ready: list[Delivery]) -> list[Delivery]:
        """NEWEST inputs keep their last delivery; the others their last max_queued."""
        if len(ready) < 2:  # every policy keeps one delivery (max_queued >= 1, Dataflow)
            return ready
        # deliveries per input, then how many of each input's oldest go: counts rather than
        # lists of indices and a set of them (a step that drops nothing, nearly every one,
        # builds one small dict)
        per_input: dict[tuple[str, str], int] = {}
        for d in ready:
            key = (d.source, d.stream)
            per_input[key] = per_input.get(key, 0) + 1
        excess: dict[tuple[str, str], int] = {}
        for key, count in per_input.items():
            inp = self._inputs[key]
            newest = inp.policy is QueuePolicy.NEWEST
            n = count - (1 if newest else inp.max_queued)
            if n > 0:
                excess[key] = n
                if newest:
                    self.superseded += n
                else:
                    self.count_dropped(*key, n, "queue full at the step")
        if not excess:
            return ready
        kept = []
        for d in ready:  # in delivery order: each input's first `n` are its oldest
            key = (d.source, d.stream)
            n = excess.get(key, 0)
            if n:
                excess[key] = n - 1
            else:
                kept.append(d)
        return kept

    # -- the clock, for runtimes that join or fall behind it (realtime) ----------------------
    def join_clock(self, t_us: int) -> bool:
        """Start stepping at the first period boundary at or after t_us (a late joiner does
        not replay every period since 0); True if the schedule moved."""
        if t_us <= self.next_step_us or self.next_step_us >= NEVER:
            return False
        self.next_step_us += -(-(t_us - self.next_step_us) // self.period_us) * self.period_us
        return True

    @property
    def resumes(self) -> bool:
        """Whether the core takes up from its previous process's messages (Resumes)."""
        return isinstance(self.core, Resumes)

    def resume(self, own: Mapping[str, bytes], t_us: int) -> str | None:
        """Hand the core the newest message its previous process published on each stream
        (bytes as they crossed the wire); only messages this service signed are taken. What
        it resumed from, or None when it starts over."""
        if not isinstance(self.core, Resumes):
            return None
        mine: dict[str, Message] = {}
        for stream, data in own.items():
            try:
                msg = decode(data)
            except WireError:
                continue
            if stream in self._seq and msg.source == self.name:
                mine[stream] = msg
        return self.core.resume(mine, t_us / 1e6) if mine else None

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
        receivers = self._receivers.get(stream)
        if receivers is None:
            raise ValueError(f"{self.name}: emitted on undeclared stream {stream!r}")
        seq = self._seq[stream] = self._seq[stream] + 1
        t = t_us / 1e6
        name = self.name
        data = encode(msg, source=name, seq=seq, sent=t)
        net = self.net
        if isinstance(msg, TruthState):  # the vehicle's own host ranges from its own truth
            net.observe_vehicle(msg.x, msg.y)
        size = len(data)
        schedule: dict[str, tuple[int, ...]] = {}
        for receiver, spec in receivers:
            if spec.tap:  # a simulation tap is no link: handed over at the next tick
                schedule[receiver] = (t_us,)
                continue
            times = net.decide(name, stream, receiver, seq, t, size).delivered_at
            # one copy, or none, nearly always: no generator for it (a fleet's truth goes to
            # every vehicle's sensor)
            schedule[receiver] = (
                (to_us(times[0]),) if len(times) == 1 else tuple(to_us(x) for x in times)
            )
        return Outgoing(stream, seq, data, schedule)

    def wake_deliveries_us(self, out: list[Outgoing]) -> dict[str, int]:
        """Earliest delivery to a wake input per receiver, among messages just sent: what the
        lockstep coordinator must know before the receivers themselves have seen them."""
        best: dict[str, int] = {}
        for o in out:
            for receiver, spec in self._receivers[o.stream]:
                times = o.schedule.get(receiver)
                if spec.wake and times:
                    best[receiver] = min(best.get(receiver, NEVER), times[0])
        return best

    def published(self) -> dict[str, int]:
        """Last seq published per output stream."""
        return dict(self._seq)

    def _measured_delay(self, key: tuple[str, str], h: DurationHistogram) -> MeasuredDelay:
        """The delays measured on the incoming link of input `key`, as the wire record."""
        p50, p95 = h.quantiles(0.5, 0.95)
        return MeasuredDelay(
            link=link_name(*key, self.name),
            delivered=h.count,
            delay_p50=p50,
            delay_p95=p95,
            delay_max=h.max,
        )

    def link_stats(self, t: float) -> LinkStats:
        """Counters of every outgoing link so far, as the wire message."""
        links = tuple(
            LinkCounters(
                link=name,
                **{count: getattr(s, count) for count in LINK_COUNTS},
                delay_p50=s.delay_p50_s,
                delay_p95=s.delay_p95_s,
                delay_p99=s.delay_p99_s,
                bytes_sent=s.bytes_sent,
            )
            for name, s in self.net.snapshots().items()
        )
        # (keys are unique: sorting the items never compares two histograms)
        measured = tuple(self._measured_delay(k, a) for k, a in sorted(self._measured.items()))
        core = self.core
        return LinkStats(
            stamp=t,
            links=links,
            measured=measured,
            inputs_dropped=self.drops.by_link(),
            inputs_rejected=(
                dict(cast(JudgesInputs, core).inputs_rejected) if self._judges else {}
            ),
            resets=dict(cast(RestartsFilters, core).resets) if self._restarts else {},
            counters={
                **(cast(CountsForStats, core).stats_counters if self._counts else {}),
                **self.runtime_counters(),
            },
        )
