"""A realtime service process: hosts one core on the (optionally scaled) wall clock."""

from __future__ import annotations

import logging
import sys
import time

from common.bus import Bus, Inbox, Liveliness, Received
from common.messages import Tick, encode_routing
from common.runtime.distributed.service_process import (
    ServiceSetup,
    routing_for,
    service_main,
    wire,
)
from common.runtime.model.host import STATS_STREAM, to_us

log = logging.getLogger("tidelink.realtime")


class RealtimeService:
    """Steps its core when the scaled wall clock reaches each period; applies the link model's
    delivery times as timers (a message is handed over at max(modelled time, arrival)).

    The clock starts with the first Tick seen: a service that joins late (restarted by the
    launcher, or started on another host) starts its schedule at the Tick's mission time
    instead of replaying every period since 0. A step that falls behind by whole periods (a
    long replan, a descheduled process) skips the missed periods, as a real-time loop must:
    commands stamped in the past would only be rejected as stale. The service stops on a stop
    Tick, or when the clock's liveliness token vanishes (its launcher is gone).
    """

    def __init__(self, setup: ServiceSetup) -> None:
        self.name = setup.name
        self.host = setup.host
        self.keys = setup.keys
        self.bus_cfg = setup.bus_cfg
        self.scale = setup.scenario.runtime.time_scale
        self.t0: float | None = None
        self.ticks = 0
        self.skipped = 0  # periods skipped because the loop fell behind

    def now_us(self) -> int:
        assert self.t0 is not None
        return to_us((time.monotonic() - self.t0) * self.scale)

    def run(self) -> int:
        with Bus(self.bus_cfg, self.keys, low_latency=True, identity=self.name) as bus:
            inbox = Inbox()
            pubs = wire(bus, self.host, self.keys, inbox, express=False)
            bus.declare_alive(self.name)
            while True:
                timeout = None
                if self.t0 is not None:
                    nxt = self.host.next_event_us()
                    timeout = max(0.0, (nxt - self.now_us()) / 1e6 / self.scale)
                ev = inbox.get(timeout=timeout)
                if ev is not None and self._handle(ev):
                    if self.t0 is not None:
                        # the final statistics, with source and seq like every message (a
                        # run's record refuses one without: anyone could have put it)
                        self.ticks += 1
                        final = self.host.publish_stats(self.ticks, self.now_us())
                        pubs[STATS_STREAM].put_bytes(
                            final.data, encode_routing(self.ticks, final.schedule)
                        )
                    if self.skipped:
                        log.info(
                            "%s: skipped %d periods in all (fell behind)", self.name, self.skipped
                        )
                    return 0
                # run every event that is due (a step, or a delivery to a wake input)
                while self.t0 is not None:
                    now = self.now_us()
                    # a step that fell behind by whole periods skips them (see the docstring)
                    self.skipped += self.host.skip_missed(now)
                    t_us = self.host.next_event_us()
                    if now < t_us:
                        break
                    self.ticks += 1
                    # the core sees the scheduled event time; late wake-ups do not skew periods
                    for o in self.host.run_tick(self.ticks, t_us):
                        pubs[o.stream].put_bytes(o.data, encode_routing(self.ticks, o.schedule))

    def _join(self, t_us: int) -> None:
        """Start the clock at mission time t_us (0 at the start; later for a late joiner)."""
        self.t0 = time.monotonic() - t_us / 1e6 / self.scale
        if self.host.join_clock(t_us):
            log.info("%s: joined the mission clock at t=%.3f s", self.name, t_us / 1e6)

    def _handle(self, ev: Received | Liveliness) -> bool:
        """Take one event; True when the run is over."""
        if isinstance(ev, Liveliness):
            if not ev.alive:
                log.info("%s: the mission clock went away; stopping", self.name)
            return not ev.alive
        if isinstance(ev.msg, Tick):
            if ev.msg.stop:
                return True
            if self.t0 is None:
                self._join(ev.msg.time_us)
            return False
        if self.t0 is None:
            return False
        routed = routing_for(ev, self.name)
        times = routed[1] if routed is not None else ()
        if times:
            arrived = self.now_us()
            service, stream = self.keys.split(ev.key)
            # -1: realtime has no shared tick numbers; delivery waits for the modelled time
            self.host.accept(ev.msg, service, stream, tuple(max(t, arrived) for t in times), -1)
        return False


def main(argv: list[str] | None = None) -> int:
    return service_main(RealtimeService, __doc__ or "", argv)


if __name__ == "__main__":
    sys.exit(main())
