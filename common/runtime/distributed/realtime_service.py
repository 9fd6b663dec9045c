"""A realtime service process: hosts one core on the (optionally scaled) wall clock."""

from __future__ import annotations

import logging
import sys
import time
from collections.abc import Mapping

from common.bus import Bus, Inbox, Liveliness, Publisher, Received
from common.messages import Tick, encode_routing
from common.runtime.distributed.claim import claim
from common.runtime.distributed.loop_times import LoopTimes
from common.runtime.distributed.service_process import (
    ServiceSetup,
    resume_from_tap,
    service_main,
    take_data,
    wire,
)
from common.runtime.model.host import STATS_STREAM, to_us
from common.runtime.processes.timer_slack import tighten_timer_slack

log = logging.getLogger("tidelink.realtime")

# Events a service lets wait before shedding the oldest samples (a flood it cannot keep up
# with): at ~20 us an event, 1024 are ~20 ms of backlog. Ticks and liveliness are never shed.
INBOX_MAX_PENDING = 1024
# A Tick that moves a service's clock forward by more than this (wall seconds) means the
# service is catching up (it just joined, or was frozen): it takes every event already
# waiting before its due steps run (see RealtimeService._take).
CATCH_UP_S = 0.01
# A Tick that would move a joined service's clock ahead by more than this (wall seconds) is a
# leap no network delay explains: the launcher's clock runs at the scale, as ours does, and
# the least-delayed Tick already set ours. Such a Tick counts only once the next Tick
# confirms it (then the smaller leap is taken): one forged Tick cannot move the clock.
MAX_TICK_LEAP_S = 0.5
# A delivery modelled further ahead than this (mission seconds) is no link's delay but a
# forged routing: it would hold a queue slot until then.
MAX_DELIVERY_AHEAD_S = 60.0
# How long (wall seconds) a service waits for the mission clock's liveliness token to come
# back before it stops. The token also vanishes when this service's own session is cut: a
# router closes a client it could not reach (a host cut off for over a second, see
# common/bus/session.py), the client reconnects and sees the token again within a fraction
# of a second (tests/test_netns_launch.py); a launcher that is really gone never returns.
# The grace counts only while this session is connected: cut off itself (its host's link
# down past its Zenoh lease), a service saw every token vanish, the clock's with them, and
# says nothing of the launcher until it is back; it waits to rejoin for as long as the
# launcher waits for a service that left (`runtime.start_timeout_s`).
CLOCK_GRACE_S = 3.0
# How long (wall seconds) a restarted core that resumes waits for the run's tap to answer
# with what its previous process published (the launcher's tap answers within milliseconds)
RESUME_QUERY_S = 2.0


class RealtimeService:
    """Steps its core when the scaled wall clock reaches each period; applies the link model's
    delivery times as timers (a message is handed over at max(modelled time, arrival)).

    The clock starts with the first Tick seen: a service that joins late (restarted by the
    launcher, or started on another host) starts its schedule at the Tick's mission time
    instead of replaying every period since 0. Every later Tick corrects it (`_refine`): a
    Tick's time was read before it travelled, so each one bounds the launcher's time 0 from
    above, and the earliest bound is the nearest (a one-way minimum-delay filter, as NTP
    keeps its minimum-delay sample). The first Tick reaches a service that is still starting
    up late by milliseconds, different in every process; uncorrected, that skew between two
    services' clocks was in every message's age and made a zero-delay hop wait for it (a
    message is handed over at max(its delivery time, arrival) on the receiver's clock).

    A step that falls behind by whole periods (a long replan, a descheduled process) skips
    the missed periods, as a real-time loop must: commands stamped in the past would only be
    rejected as stale. A Tick that would leap the clock ahead by more than MAX_TICK_LEAP_S
    once the clock runs is refused unless the next Tick confirms it (one forged Tick cannot
    move it). The service stops on a stop Tick, or when the clock's liveliness token
    stays gone for CLOCK_GRACE_S (its launcher is gone, not merely this service's connection).

    A flood cannot stall the loop: the inbox sheds its oldest samples once INBOX_MAX_PENDING
    wait, each input holds at most its max_queued deliveries, and what is dropped or refused
    (no routing, a forged delivery time, the wrong type) is counted in the stats and logged
    once per input and reason per mission second.
    """

    def __init__(self, setup: ServiceSetup) -> None:
        self.name = setup.name
        self.host = setup.host
        self.keys = setup.keys
        self.bus_cfg = setup.bus_cfg
        self.scale = setup.scenario.runtime.time_scale
        self.t0: float | None = None
        self.ticks = 0
        self.clock_lost_at: float | None = None  # wall time the clock's token vanished
        self.cut_off_at: float | None = None  # wall time this session was seen cut off
        self.rejoin_timeout_s = setup.scenario.runtime.start_timeout_s
        self._catching_up = False  # the last Tick moved the clock by more than CATCH_UP_S
        # the Tick that started the clock and those queued with it: they set it freely
        self._joining = False
        self._leap_t0: float | None = None  # a leap ahead waiting for the next Tick's word
        self._bus: Bus | None = None
        self.times = LoopTimes()
        self.host.runtime_counters = self.times.counters
        # when (mission us) the core prepares its next step (core.Prepares), while one waits
        self.prepare_delay_us = to_us(setup.scenario.runtime.prepare_delay_s)
        self._prepare_at_us: int | None = None

    @property
    def skipped(self) -> int:
        """Periods skipped because the loop fell behind."""
        return self.times.skipped

    def now_us(self) -> int:
        assert self.t0 is not None
        return to_us((time.monotonic() - self.t0) * self.scale)

    def run(self) -> int:
        tighten_timer_slack()  # each step's timed wait ends on time, not up to 50 us late
        with Bus(self.bus_cfg, self.keys, low_latency=True, identity=self.name) as bus:
            claim(bus, self.keys, self.name)  # RoleTaken: another one is in the run
            self._bus = bus
            inbox = Inbox(max_pending=INBOX_MAX_PENDING, keep=self.keys.is_tick, on_shed=self._shed)
            pubs = wire(bus, self.host, self.keys, inbox, express=False)
            bus.declare_alive(self.name)
            while True:
                timeout = None
                if self.t0 is not None:
                    nxt = self.host.next_event_us()
                    if self._prepare_at_us is not None:
                        nxt = min(nxt, self._prepare_at_us)
                    timeout = max(0.0, (nxt - self.now_us()) / 1e6 / self.scale)
                if self.clock_lost_at is not None:
                    left = self.clock_lost_at + CLOCK_GRACE_S - time.monotonic()
                    timeout = max(0.0, left if timeout is None else min(timeout, left))
                if self._take(inbox, timeout) or self._clock_gone():
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
                self._run_due(pubs)

    def _run_due(self, pubs: Mapping[str, Publisher]) -> None:
        """Run every event due now (a step, deliveries to wake inputs), then go back to the inbox.

        `now` is read once. A step that takes longer than a period must not chain straight
        into the next one: the loop would never take what waits in its inbox again, neither
        the stop Tick nor the inputs that would make its steps short again
        (docs/notes/code-realtime-step-returns-to-inbox.md)."""
        if self.t0 is None:
            return
        now = self.now_us()
        woke_at = time.perf_counter()
        if self._prepare_at_us is not None and self._prepare_at_us <= now:
            self._prepare()  # its time has come
        # a step that fell behind by whole periods skips them (see the class docstring)
        self.times.skipped += self.host.skip_missed(now)
        while (t_us := self.host.next_event_us()) <= now:
            if self._prepare_at_us is not None:
                self._prepare()  # before the core sees anything more
            self.ticks += 1
            woke = time.perf_counter()
            # the core sees the scheduled event time; late wake-ups do not skew periods
            out = self.host.run_tick(self.ticks, t_us)
            stepped = time.perf_counter()
            for o in out:
                pubs[o.stream].put_bytes(o.data, encode_routing(self.ticks, o.schedule))
            if out:  # the ticks on a message's way through (a loop's latency is theirs)
                late_s = (now - t_us) / 1e6 / self.scale + (woke - woke_at)
                self.times.record(late_s, stepped - woke, time.perf_counter() - stepped)
            if self.host.prepare_pending:  # the next step's work that waits for none of its inputs
                self._prepare_at_us = t_us + self.prepare_delay_us
                if self.prepare_delay_us <= 0:
                    self._prepare()

    def _prepare(self) -> None:
        """Let the core prepare its next step now (RuntimeConfig.prepare_delay_s)."""
        self._prepare_at_us = None
        start = time.perf_counter()
        if self.host.prepare():
            self.times.record_prepare(time.perf_counter() - start)

    def _take(self, inbox: Inbox, timeout: float | None) -> bool:
        """Wait up to `timeout` for an event and take it; while catching up, take every event
        already waiting too, before any step runs. True when the run is over.

        A process frozen (SIGSTOP) before its first Tick finds a Tick per RETELL_S queued,
        each one newer: taken one at a time, each would move its clock by one re-tell and
        let it step through the past. Only then: otherwise (a flood above all) one event at
        a time, with the due steps between, so a burst of copies cannot crowd a fresh
        message out of its input's queue before it is handed over."""
        ev = inbox.get(timeout=timeout)
        while ev is not None:
            if self._handle(ev):
                return True
            if not self._catching_up:
                break
            ev = inbox.get(timeout=0.0)
        self._joining = False  # what was queued when the clock started has been taken
        return False

    def _join(self, t_us: int) -> None:
        """Start the clock at mission time t_us (0 at the start; later for a late joiner)."""
        self.t0 = time.monotonic() - t_us / 1e6 / self.scale
        self._catching_up = self._joining = True
        if self.host.join_clock(t_us):
            log.info("%s: joined the mission clock at t=%.3f s", self.name, t_us / 1e6)
            if self._bus is not None:  # a restarted core may take up where its last one was
                resume_from_tap(self._bus, self.host, self.keys, t_us, timeout_s=RESUME_QUERY_S)

    def _refine(self, t_us: int) -> None:
        """Move time 0 earlier if this Tick (mission time t_us when it was sent) says the
        launcher's clock is ahead of ours: mission time only ever jumps forward, by the
        difference between this Tick's delay and the least delay seen so far."""
        assert self.t0 is not None
        t0 = time.monotonic() - t_us / 1e6 / self.scale
        if self.t0 - t0 > MAX_TICK_LEAP_S and not self._joining:
            # a leap ahead (MAX_TICK_LEAP_S): taken only when the next Tick leaps too
            pending, self._leap_t0 = self._leap_t0, t0
            if pending is None:
                self.times.ticks_refused += 1
                n = self.times.ticks_refused
                if n == 10 ** (len(str(n)) - 1):  # the 1st, 10th, 100th...
                    log.warning(
                        "%s: a Tick at t=%.2f s would move the clock %.2f s ahead (mission "
                        "time now %.2f s): refused unless the next Tick confirms it (%d so far)",
                        self.name,
                        t_us / 1e6,
                        (self.t0 - t0) * self.scale,
                        self.now_us() / 1e6,
                        n,
                    )
                return
            t0 = max(t0, pending)  # the smaller of the two leaps
            leap_s = (self.t0 - t0) * self.scale
            log.info("%s: the clock leapt %.2f s ahead, confirmed by two Ticks", self.name, leap_s)
        self._leap_t0 = None
        self._catching_up = t0 < self.t0 - CATCH_UP_S
        self.t0 = min(self.t0, t0)

    def _shed(self, key: str, n: int) -> None:
        """The inbox shed n samples of `key`: count them against that input."""
        try:
            service, stream = self.keys.split(key)
        except ValueError:
            return
        self.host.count_dropped(service, stream, n, "inbox full (the loop fell behind)")

    def _clock_gone(self) -> bool:
        """Whether the clock's token has been gone for CLOCK_GRACE_S while this session was
        connected, or this session has been cut off for rejoin_timeout_s: the run is over."""
        if self.clock_lost_at is None:
            return False
        now = time.monotonic()
        if self._bus is not None and not self._bus.connected():
            if self.cut_off_at is None:
                self.cut_off_at = now
                log.warning(
                    "%s: cut off from the router; waiting up to %.0f s to rejoin",
                    self.name,
                    self.rejoin_timeout_s,
                )
            if now < self.cut_off_at + self.rejoin_timeout_s:
                self.clock_lost_at = now  # the grace starts once we are back
                return False
            log.info("%s: could not rejoin the router; stopping", self.name)
            return True
        if self.cut_off_at is not None:
            log.info(
                "%s: rejoined the router %.1f s after finding itself cut off",
                self.name,
                now - self.cut_off_at,
            )
            self.cut_off_at = None
        if now < self.clock_lost_at + CLOCK_GRACE_S:
            return False
        log.info("%s: the mission clock went away; stopping", self.name)
        return True

    def _handle(self, ev: Received | Liveliness) -> bool:
        """Take one event; True when the run is over."""
        if isinstance(ev, Liveliness):
            if ev.alive:
                if self.clock_lost_at is not None:
                    log.info("%s: the mission clock is back", self.name)
                self.clock_lost_at = self.cut_off_at = None
            elif self.clock_lost_at is None:
                log.info(
                    "%s: the mission clock's token vanished; waiting %.0f s for it",
                    self.name,
                    CLOCK_GRACE_S,
                )
                self.clock_lost_at = time.monotonic()
            return False
        if self.keys.is_tick(ev.key):  # only the clock's keys carry ticks
            if not isinstance(ev.msg, Tick):
                return False
            if ev.msg.stop:
                return True
            if self.t0 is None:
                self._join(ev.msg.time_us)
            else:
                self._refine(ev.msg.time_us)
            return False
        if self.t0 is None:
            return False
        routed = take_data(self.host, self.keys, ev)
        if routed is None or not routed.times_us:
            return False
        arrived = self.now_us()
        if max(routed.times_us) - arrived > MAX_DELIVERY_AHEAD_S * 1e6:
            self.host.count_dropped(routed.source, routed.stream, 1, "delivery time too far ahead")
            return False
        # -1: realtime has no shared tick numbers; delivery waits for the modelled time
        times = tuple(max(t, arrived) for t in routed.times_us)
        self.host.accept(ev.msg, routed.source, routed.stream, times, -1)
        return False


def main(argv: list[str] | None = None) -> int:
    return service_main(RealtimeService, __doc__ or "", argv)


if __name__ == "__main__":
    sys.exit(main())
