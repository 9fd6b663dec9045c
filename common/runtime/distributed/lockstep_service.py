"""A lockstep service process: hosts one core, steps only when the coordinator ticks.

A tick sent early (lookahead.py) may name services still running the tick before (`after`):
the service then waits for their acks, which it hears directly (it subscribes to the acks of
the predictable services it reads), and for the data they report, and steps as soon as they
are in: the step after the planner's waits one hop for it, not two and the coordinator's.
"""

from __future__ import annotations

import logging
import sys
import time

from common.bus import Bus, Inbox, Liveliness, Received
from common.messages import Tick, TickAck, encode_routing
from common.runtime.distributed.claim import claim
from common.runtime.distributed.lookahead import Lookahead
from common.runtime.distributed.service_process import (
    ServiceSetup,
    service_main,
    take_data,
    wire,
)
from common.runtime.model.seqwindow import SeqWindow, max_seq_gap

log = logging.getLogger("tidelink.lockstep")
MAX_ACKS_KEPT = 64  # feeders' acks held before those of past ticks are dropped


class LockstepService:
    """Waits for each tick, makes sure it holds every message sent before it, runs the tick."""

    def __init__(self, setup: ServiceSetup) -> None:
        self.scenario = setup.scenario
        self.name = setup.name
        self.host = setup.host
        self.keys = setup.keys
        self.bus_cfg = setup.bus_cfg
        # which seqs of each input arrived: a tick's data are here when the complete prefix
        # reaches its watermark (counting messages instead, one forged message on an input
        # key would make the service step before the real one arrives)
        gap = max_seq_gap(self.host.flow, self.scenario.run.max_time_s)
        self.received = {f"{i.source}/{i.stream}": SeqWindow(gap) for i in self.host.inputs}
        self.timeout_s = self.scenario.runtime.tick_timeout_s
        # the acks it may be told to wait for: of the predictable services it reads
        predictable = Lookahead.of(setup.mission).period_us
        self.feeders = sorted({i.source for i in self.host.inputs} & set(predictable))
        self.acks: dict[tuple[str, int], TickAck] = {}  # theirs, by (service, tick)

    def run(self) -> int:
        # The Bus defaults (batching publishers, callbacks handed to a Python thread) make a
        # faster tick loop on the default mission than express publishers and callbacks on
        # Zenoh's network thread: Zenoh sends a batch as soon as its link is free, so nothing
        # waits for a batch to fill.
        with Bus(self.bus_cfg, self.keys, identity=self.name) as bus:
            claim(bus, self.keys, self.name)  # RoleTaken: another one is in the run
            inbox = Inbox()
            # data are quiet: taken when the tick comes, not each on arrival (a wake-up per
            # message was most of a fleet sensor's CPU)
            pubs = wire(bus, self.host, self.keys, inbox, express=False, quiet=True)
            for feeder in self.feeders:
                bus.subscribe(self.keys.ack(feeder), inbox)
            ack_pub = bus.publisher_on(self.keys.ack(self.name))
            bus.declare_alive(self.name)
            while True:
                tick = self._next_tick(inbox)
                if not tick.stop and self.name not in tick.due:
                    continue  # nothing due here: messages keep arriving into the host
                self._wait_for(inbox, self._after(inbox, tick))
                if tick.stop:
                    out = [self.host.publish_stats(tick.tick, tick.time_us)]
                else:
                    out = self.host.run_tick(tick.tick, tick.time_us)
                for o in out:
                    pubs[o.stream].put_bytes(o.data, encode_routing(tick.tick, o.schedule))
                ack_pub.put(
                    TickAck(
                        stamp=tick.time_us / 1e6,
                        tick=tick.tick,
                        service=self.name,
                        published={f"{self.name}/{k}": v for k, v in self.host.published().items()},
                        next_us=self.host.next_event_us(),
                        wakes=self.host.wake_deliveries_us(out),
                    )
                )
                if tick.stop:
                    self._await_release(inbox)
                    return 0
                # off the tick's critical path: the coordinator goes on meanwhile, and the
                # next tick for this service waits in its inbox until this is done
                self.host.prepare()
                if len(self.acks) > MAX_ACKS_KEPT:  # the feeders' acks of ticks gone by
                    self.acks = {key: a for key, a in self.acks.items() if key[1] >= tick.tick}

    def _after(self, inbox: Inbox, tick: Tick) -> dict[str, int]:
        """The watermarks of `tick`, with those its `after` services' acks report (waited for)."""
        if not tick.after:
            return tick.watermarks
        marks = dict(tick.watermarks)
        deadline = time.monotonic() + self.timeout_s
        for service, k in sorted(tick.after.items()):
            if service not in self.feeders:
                raise RuntimeError(f"{self.name}: tick {tick.tick} waits for {service}, not read")
            while (service, k) not in self.acks:
                ev = inbox.get(timeout=max(0.0, deadline - time.monotonic()), data=False)
                if ev is None:
                    raise TimeoutError(f"{self.name}: {service}'s ack of tick {k} never came")
                if self._handle(ev) is not None:
                    raise RuntimeError(f"{self.name}: a new tick came before {service}'s ack")
            marks.update(self.acks[(service, k)].published)
        return marks

    def _await_release(self, inbox: Inbox) -> None:
        """Stay connected until the coordinator leaves, so the final ack is surely delivered."""
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            ev = inbox.get(timeout=max(0.0, deadline - time.monotonic()), data=False)
            if isinstance(ev, Liveliness) and not ev.alive:
                return
        log.warning(
            "%s: coordinator did not release us in %s s; exiting", self.name, self.timeout_s
        )

    def _handle(self, ev: Received | Liveliness | None) -> Tick | None:
        if ev is None:
            raise TimeoutError(f"{self.name}: nothing from the coordinator for {self.timeout_s} s")
        if isinstance(ev, Liveliness):
            if not ev.alive:
                raise SystemExit(f"{self.name}: the coordinator went away; exiting")
            return None
        if self.keys.is_tick(ev.key):  # only the clock's keys carry ticks
            return ev.msg if isinstance(ev.msg, Tick) else None
        acked_by = self.keys.acked_by(ev.key)
        if acked_by is not None:  # a feeder's ack, on its own key only
            if isinstance(ev.msg, TickAck) and ev.msg.service == acked_by:
                self.acks[(acked_by, ev.msg.tick)] = ev.msg
            return None
        service, stream = self.keys.split(ev.key)
        window = self.received.get(f"{service}/{stream}")
        if window is not None and ev.msg.source == service and window.plausible(ev.msg.seq):
            window.take(ev.msg.seq)
        routed = take_data(self.host, self.keys, ev)
        if routed is not None and routed.times_us:
            self.host.accept(
                ev.msg, routed.source, routed.stream, routed.times_us, routed.sent_tick
            )
        return None

    def _next_tick(self, inbox: Inbox) -> Tick:
        while True:
            tick = self._handle(inbox.get(timeout=self.timeout_s, data=False))
            if tick is not None:
                return tick

    def _wait_for(self, inbox: Inbox, watermarks: dict[str, int]) -> None:
        deadline = time.monotonic() + self.timeout_s
        for key, seq in watermarks.items():
            while key in self.received and self.received[key].prefix < seq:
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.name}: {key} seq {seq} never arrived")
                if self._handle(inbox.get(timeout=left)) is not None:
                    raise RuntimeError(f"{self.name}: a new tick came before the data of the last")


def main(argv: list[str] | None = None) -> int:
    return service_main(LockstepService, __doc__ or "", argv)


if __name__ == "__main__":
    sys.exit(main())
