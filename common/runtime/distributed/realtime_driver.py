"""The realtime runtime's driver: wait for every service, run the mission clock, record the
run, apply restart policies, and end on the mission's end, max_time or a stop request.

A service that ends for good (its policy does not restart it, or its token is gone too long)
fails the run, except in a fleet once the clock runs: there a vehicle that lost a service goes
on without it (a lost planner: its vehicle holds, then fails safe, on its own watchdog) and so
does the rest of the fleet, which still sees it (its last intent, then its sonar track); the
run ends as it would have, and says what was lost (RunResult.failure). As a fleet at sea.

One driver for every realtime run: `run_realtime` (this process is the router, services are
forked here) and `tidelink launch` (a router process, supervised services, remote ones).
"""

from __future__ import annotations

import time
from pathlib import Path

from common.bus import Event, Inbox, Liveliness
from common.bus.tap import WatchTap
from common.config.scenario import Scenario
from common.jsonsafe import JsonObject
from common.messages import Tick, TickAck
from common.runtime.distributed.bringup import run_locally
from common.runtime.distributed.claim import ClaimWatch
from common.runtime.distributed.clock import MissionClock
from common.runtime.distributed.observer import RunContext
from common.runtime.distributed.ticks import TickSender
from common.runtime.model.dataflow import vehicle_of
from common.runtime.model.mission import mission_record
from common.runtime.model.record import Renumbering
from common.runtime.model.result import RunResult
from common.runtime.processes.supervisor import (
    Exited,
    GaveUp,
    Restarted,
    Restarting,
    ServiceFailed,
)

SERVICE_MODULE = "common.runtime.distributed.realtime_service"

# wall seconds between re-publications of the mission time: late joiners start from it, and
# every service corrects its clock with it (realtime_service: the least-delayed Tick wins)
RETELL_S = 0.2
CHECK_EVERY_S = 0.1  # wall seconds between supervision checks and progress reports
FINAL_STATS_S = 5.0  # wall seconds to wait for the services' final statistics after the end
GONE_GRACE_S = 0.5  # after a service's token went: its last frames may still be on their way
# how far (mission seconds) a message's stamp may be ahead of this clock when it is recorded:
# a service's clock is set by the least-delayed Tick, so it is never ahead of the launcher's
# but by the jitter of reading two monotonic clocks; beyond that it is refused ("future")
AHEAD_S = 0.5


class GoneGrace:
    """Whether every service's token has been gone for `grace_s`, each counted from when its
    own token was first seen gone (all at once, not one after another)."""

    def __init__(self, names: set[str], grace_s: float) -> None:
        self.names = names
        self.grace_s = grace_s
        self.gone_at: dict[str, float] = {}

    def over(self, alive: set[str], now: float) -> bool:
        for name in self.names - alive:
            self.gone_at.setdefault(name, now)
        return all(
            name not in alive and now - self.gone_at[name] > self.grace_s for name in self.names
        )


class RealtimeDriver:
    """Drives one realtime run; `sup` runs the local services, others join over Zenoh."""

    def __init__(self, ctx: RunContext) -> None:
        scenario = ctx.scenario
        self.scenario = scenario
        self.mission = ctx.mission
        self.names = set(ctx.mission.dataflow.names)
        self.keys = ctx.keys
        self.sup = ctx.sup
        self.observer = ctx.observer
        self.stop = ctx.stop
        self.timeout_s = scenario.runtime.start_timeout_s
        self.record = mission_record(ctx.mission)
        self.alive: set[str] = set()
        self.ever_alive: set[str] = set()
        self.gone_since: dict[str, float] = {}
        self.renumbering = Renumbering(self.record)  # a restarted service's seqs start over
        self.clock: MissionClock | None = None
        self.ending = False
        self.fleet = bool(scenario.vehicles)
        self.lost: dict[str, str] = {}  # fleet services gone for good, and how
        self.claims = ClaimWatch()  # who holds each role: a second claimant is an alarm

    # -- events ------------------------------------------------------------------------------
    def supervise(self) -> None:
        """Report exits and restarts; a service its policy does not restart fails the run."""
        for ev in self.sup.poll():
            if isinstance(ev, Exited):
                self.observer.event(ev.text)
            elif isinstance(ev, Restarting):
                self.observer.event(
                    f"restarting {ev.name!r} in {ev.delay_s:.2f} s "
                    f"(restart {ev.attempt} of {ev.max_restarts})"
                )
            elif isinstance(ev, Restarted):
                self.observer.event(f"restarted {ev.name!r} (pid {ev.pid}, restart {ev.attempt})")
            elif isinstance(ev, GaveUp):
                self._lose(ev.name, ev.text)

    def take(self, ev: Event | None) -> None:
        """Record a message, or track a liveliness change."""
        if ev is None:
            return
        if isinstance(ev, Liveliness):
            if (alarm := self.claims.seen(ev.key, ev.alive)) is not None:
                self.observer.event(alarm)
            elif not self.keys.is_claim(ev.key):
                self._liveliness(ev.key.rsplit("/", 1)[-1], ev.alive)
            return
        msg = ev.msg
        if isinstance(msg, Tick | TickAck):
            return
        try:
            service, stream = self.keys.split(ev.key)
        except ValueError:
            return
        # no service's clock runs ahead of this one: a later stamp is a forgery (or a forged
        # Tick's doing), and would carry the run's metrics past its end
        latest_s = None if self.clock is None else self.clock.now_us() / 1e6 + AHEAD_S
        recorded = self.renumbering.add(service, stream, msg, latest_s=latest_s)
        if recorded is not None:  # a refused message is not shown either
            self.observer.message(service, stream, recorded)

    def _liveliness(self, service: str, alive: bool) -> None:
        if service not in self.names:
            return
        if not alive:
            self.alive.discard(service)
            self.gone_since[service] = time.monotonic()
            if self.clock is not None and not self.ending:
                self.observer.event(
                    f"service {service!r} left (liveliness token gone) at "
                    f"t={self.clock.now_us() / 1e6:.2f} s"
                )
            return
        self.alive.add(service)
        self.gone_since.pop(service, None)
        if service in self.ever_alive and self.clock is not None:
            self.renumbering.rejoined(service)
            t_us = self.clock.tell()  # its clock starts from this Tick
            self.observer.event(f"service {service!r} rejoined at t={t_us / 1e6:.2f} s")
        self.ever_alive.add(service)

    def _check_gone(self) -> None:
        now = time.monotonic()
        for service, since in list(self.gone_since.items()):
            if now - since > self.timeout_s and not self.sup.pending_restart(service):
                self._lose(
                    service,
                    f"service {service!r} has been gone (no liveliness token) "
                    f"for {self.timeout_s:g} s",
                )

    def _lose(self, service: str, why: str) -> None:
        """A service ended for good: the run fails, unless a fleet's run is under way and
        another vehicle still has all of its services (then it goes on without this one)."""
        vehicle = vehicle_of(service)
        crippled = {vehicle_of(n) for n in self.lost} | {vehicle}
        whole = {vehicle_of(n) for n in self.names} - crippled
        if not (self.fleet and self.clock is not None and vehicle and whole):
            raise ServiceFailed(why)
        self.lost[service] = why
        self.names.discard(service)
        self.alive.discard(service)
        self.gone_since.pop(service, None)
        self.observer.event(
            f"{why}: vehicle {vehicle} goes on without {service!r}, and the fleet with it "
            f"(t={self.clock.now_us() / 1e6:.2f} s)"
        )

    # -- phases ------------------------------------------------------------------------------
    def await_alive(self, inbox: Inbox) -> None:
        """Wait until every mission service, local or remote, has declared its token."""
        t0 = time.monotonic()
        deadline = t0 + self.timeout_s
        while not self.alive >= self.names:
            self.stop.check()
            self.supervise()
            if time.monotonic() > deadline:
                missing = ", ".join(sorted(self.names - self.alive))
                raise ServiceFailed(
                    f"timed out after {self.timeout_s:g} s waiting for {missing} "
                    "to start (no liveliness token)"
                )
            self.take(inbox.get(timeout=0.1))
        self.observer.event(
            f"all {len(self.names)} services alive after {time.monotonic() - t0:.2f} s"
        )

    def drive(self, inbox: Inbox, pub: TickSender, tap: WatchTap | None = None) -> RunResult:
        """Run the clock (the services' frames go on their stream keys: `tap` hears them)."""
        scale = self.scenario.runtime.time_scale
        max_us = round(self.mission.max_time_s * 1e6)
        self.clock = clock = MissionClock(pub, scale)
        clock.start()
        self.observer.event(f"mission clock started (time scale x{scale:g})")
        try:
            reason = self._run_clock(inbox, clock, max_us)
        except ServiceFailed:
            # the run is over: the others leave at once, not when the clock's token has gone
            self.sup.stopping = True
            clock.tell(stop=True)
            raise
        self.ending = True
        self.sup.stopping = True  # exits are expected from now on
        t_end_us = clock.tell(stop=True)
        self.observer.progress(t_end_us / 1e6)
        self.observer.event(f"mission ended at t={t_end_us / 1e6:.2f} s: {reason}")
        self._collect_final(inbox)
        lost = "; ".join(f"{n} lost: {why}" for n, why in self.lost.items())
        metrics = self.mission.metrics(self.record)
        return RunResult(reason, t_end_us / 1e6, 0, self.record, metrics, failure=lost)

    def _run_clock(self, inbox: Inbox, clock: MissionClock, max_us: int) -> str:
        """Take the run's messages until it ends; why it ended."""
        reason = "max_time"
        next_tell = time.monotonic() + RETELL_S
        next_check = 0.0
        while True:
            if self.stop.requested:
                reason = "interrupted"
                break
            t_us = clock.now_us()
            if t_us >= max_us:
                break
            end = self.mission.observe(self.record)
            if end is not None:
                reason = end
                break
            now = time.monotonic()
            if now >= next_check:
                # process polls and the display need not run per message: on 2 cores this
                # loop shares the CPU with the services whose latency it would add to
                next_check = now + CHECK_EVERY_S
                self.supervise()
                self._check_gone()
                self.observer.progress(t_us / 1e6)
            ev = inbox.get(timeout=0.02)
            for _ in range(500):  # drain what is there, but keep an eye on the clock
                if ev is None:
                    break
                self.take(ev)
                ev = inbox.get(timeout=0.0)
            self.take(ev)
            if time.monotonic() >= next_tell:
                clock.tell()
                next_tell = time.monotonic() + RETELL_S
        return reason

    def _collect_final(self, inbox: Inbox) -> None:
        """Take the final statistics each service sends as it stops: a service is done
        GONE_GRACE_S after its token went. The token's going alone is no proof its last
        frames were taken: liveliness and data reach this process by different paths, in
        either order (a flood's or a restart's final counts were lost that way)."""
        deadline = time.monotonic() + FINAL_STATS_S
        grace = GoneGrace(self.names, GONE_GRACE_S)
        while not grace.over(self.alive, time.monotonic()):
            if time.monotonic() > deadline or self.stop.hurry:
                break
            self.take(inbox.get(timeout=0.05))
        while (ev := inbox.get(timeout=0.0)) is not None:
            self.take(ev)


def run_realtime(scenario: Scenario, raw: JsonObject, log_dir: Path | None = None) -> RunResult:
    """Run a mission in real time (scaled by runtime.time_scale) across service processes."""
    return run_locally(scenario, raw, log_dir, SERVICE_MODULE, RealtimeDriver)
