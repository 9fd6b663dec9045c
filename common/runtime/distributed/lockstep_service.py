"""A lockstep service process: hosts one core, steps only when the coordinator ticks.

It hears one message a tick and sends one back. The Tick carries every frame its service
reads that was published since it was last ticked (the coordinator, which records every
frame, forwards them); the TickAck carries the frames it published in the tick. So the
service subscribes to its ticks alone, and each due service costs a tick two messages through
the router, not one per input, output and look-ahead ack (docs/notes/0058-lockstep-hub.md).
"""

from __future__ import annotations

import logging
import sys
import time

from common.bus import CLOCK, Bus, Inbox, Liveliness, Received
from common.messages import Frame, Tick, TickAck, WireError, decode, encode_routing
from common.runtime.distributed.claim import claim
from common.runtime.distributed.service_process import ServiceSetup, route, service_main

log = logging.getLogger("tidelink.lockstep")


class LockstepService:
    """Waits for each tick, takes the frames it carries, runs the tick, acks with its own."""

    def __init__(self, setup: ServiceSetup) -> None:
        self.scenario = setup.scenario
        self.name = setup.name
        self.host = setup.host
        self.keys = setup.keys
        self.bus_cfg = setup.bus_cfg
        self.timeout_s = self.scenario.runtime.tick_timeout_s
        # the highest seq taken per input: a tick carries the frames of every service it is
        # for, so it may bring one this service took with an earlier tick
        self.taken = {(i.source, i.stream): 0 for i in self.host.inputs}
        self.last_tick = -1  # the newest tick run: the clock's ticks come in order

    def run(self) -> int:
        with Bus(self.bus_cfg, self.keys, identity=self.name) as bus:
            claim(bus, self.keys, self.name)  # RoleTaken: another one is in the run
            inbox = Inbox()
            bus.subscribe(self.keys.ticks_for(self.name), inbox)
            bus.watch_alive(inbox, self.keys.alive(CLOCK))
            # batched (not express): Zenoh sends a batch as soon as its link is free, so the
            # ack waits for nothing (docs/notes/0017-lockstep-ticks-batched.md)
            ack_pub = bus.publisher_on(self.keys.ack(self.name))
            bus.declare_alive(self.name)
            while True:
                tick = self._next_tick(inbox)
                if not tick.stop and self.name not in tick.due:
                    continue  # (a stop tick goes to every service, the others to the due)
                if tick.tick <= self.last_tick:  # one session sends them: Zenoh keeps its order
                    raise RuntimeError(f"{self.name}: tick {tick.tick} after {self.last_tick}")
                self.last_tick = tick.tick
                self._take(tick.frames)
                if tick.stop:
                    out = [self.host.publish_stats(tick.tick, tick.time_us)]
                else:
                    out = self.host.run_tick(tick.tick, tick.time_us)
                ack_pub.put(
                    TickAck(
                        stamp=tick.time_us / 1e6,
                        tick=tick.tick,
                        service=self.name,
                        next_us=self.host.next_event_us(),
                        wakes=self.host.wake_deliveries_us(out),
                        frames=tuple(
                            Frame(
                                source=self.name,
                                stream=o.stream,
                                seq=o.seq,
                                data=o.data,
                                routing=encode_routing(tick.tick, o.schedule),
                            )
                            for o in out
                        ),
                    )
                )
                if tick.stop:
                    self._await_release(inbox)
                    return 0
                # off the tick's critical path: the coordinator goes on meanwhile, and the
                # next tick for this service waits in its inbox until this is done
                self.host.prepare()

    def _take(self, frames: tuple[Frame, ...]) -> None:
        """Queue in the host the frames of this tick that it reads and has not taken yet (a
        tick carries those of every service it is for; each reader of a stream is queued every
        frame of it, in order, so one at or below the highest seq taken was taken before)."""
        for f in frames:
            key = (f.source, f.stream)
            last = self.taken.get(key)
            if last is None or f.seq <= last:
                continue
            self.taken[key] = f.seq
            try:
                msg = decode(f.data)
            except WireError as exc:
                self.host.count_dropped(f.source, f.stream, 1, "undecodable", str(exc))
                continue
            if msg.source != f.source or msg.seq != f.seq:
                self.host.count_dropped(f.source, f.stream, 1, "not its frame", msg.source)
                continue
            routed = route(self.host, f.source, f.stream, f.routing)
            if routed is not None and routed.times_us:
                self.host.accept(msg, f.source, f.stream, routed.times_us, routed.sent_tick)

    def _await_release(self, inbox: Inbox) -> None:
        """Stay connected until the coordinator leaves, so the final ack is surely delivered."""
        deadline = time.monotonic() + self.timeout_s
        while time.monotonic() < deadline:
            ev = inbox.get(timeout=max(0.0, deadline - time.monotonic()))
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
        return None

    def _next_tick(self, inbox: Inbox) -> Tick:
        while True:
            tick = self._handle(inbox.get(timeout=self.timeout_s))
            if tick is not None:
                return tick


def main(argv: list[str] | None = None) -> int:
    return service_main(LockstepService, __doc__ or "", argv)


if __name__ == "__main__":
    sys.exit(main())
