"""The lockstep runtime: one OS process per service over Zenoh, virtual time from a coordinator.

The coordinator is the clock, the recorder of everything the services publish, and the hub
every frame goes through. Tick k at time T goes to the services due at T and carries every
frame each of them reads that was published since it was last ticked; each runs the tick
exactly as the inproc runtime does and acknowledges with the frames it published and when it
next needs a tick. The coordinator records the frames (and hands them to the watch tap),
queues each for the services that read it, and jumps time to the earliest need. So a due
service costs a tick one message in and one out through the router, and waits for nothing
but its tick (docs/notes/0058-lockstep-hub.md). While only services whose outcome is
predictable are still running a tick, the next one already goes out to the services not
running it, those that read a running one as soon as its ack is in (lookahead.py). Because
the hosts, link models and delivery order are the same, the trajectory is bit-identical to
an inproc run of the same scenario and seed. `run_lockstep` makes this process the Zenoh
router and forks the services; the launcher drives the same Coordinator with its own router
and supervised processes.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import NamedTuple

from common.bus import Inbox, Liveliness, Received
from common.bus.tap import WatchTap
from common.config.scenario import Scenario
from common.jsonsafe import JsonObject
from common.messages import Tick, TickAck
from common.runtime.distributed.bringup import run_locally
from common.runtime.distributed.claim import ClaimWatch
from common.runtime.distributed.hub import FrameHub
from common.runtime.distributed.lookahead import Lookahead
from common.runtime.distributed.observer import RunContext
from common.runtime.distributed.ticks import TickSender
from common.runtime.model.host import NEVER
from common.runtime.model.mission import mission_record
from common.runtime.model.result import RunResult
from common.runtime.processes.supervisor import ServiceFailed

log = logging.getLogger("tidelink.lockstep")
SERVICE_MODULE = "common.runtime.distributed.lockstep_service"
PROGRESS_EVERY_S = 0.25  # wall seconds between progress reports to the observer


class Ahead(NamedTuple):
    """The next tick, already sent (or held to be sent) to some of its services (lookahead.py)."""

    time_us: int
    services: tuple[str, ...]
    predicted: dict[str, int]  # the next need of each service still running the last tick


class Held(NamedTuple):
    """Services of tick k+1 sent it once `feeders` (running tick k, read by them) acked k."""

    tick: int
    time_us: int
    services: tuple[str, ...]
    feeders: tuple[str, ...]


class Done(NamedTuple):
    """A tick complete: its acks, the mission's end (or None), and the next tick if it was
    started early."""

    acks: dict[str, TickAck]
    end: str | None
    ahead: Ahead | None


class Coordinator:
    """Drives the ticks of a lockstep run and records it; `sup` holds the local processes
    (any of them dying fails the run: a restarted service would lose the run's determinism)."""

    def __init__(self, ctx: RunContext) -> None:
        scenario = ctx.scenario
        self.mission = ctx.mission
        self.names = ctx.mission.dataflow.names
        self.keys = ctx.keys
        self.sup = ctx.sup
        self.observer = ctx.observer
        self.stop = ctx.stop
        self.record = mission_record(ctx.mission)
        self.acks: dict[int, dict[str, TickAck]] = {}  # by tick, then service
        self.hub = FrameHub(ctx.mission.dataflow, self.record, self.observer)
        self.held: list[Held] = []  # groups of the next tick waiting for their feeders' acks
        self.lookahead = Lookahead.of(ctx.mission)
        self._tick_no = 0  # the tick being run
        self._max_us = 0  # the run's end (drive)
        self.started_early = 0  # ticks sent to some services before the last one was done
        self.alive: set[str] = set()
        self.claims = ClaimWatch()  # who holds each role: a second claimant is an alarm
        self.finished: set[str] = set()  # services that acknowledged the stop tick
        self.stopping = False
        self.t_us = 0  # mission time of the newest tick
        self.start_timeout_s = scenario.runtime.start_timeout_s
        self.timeout_s = scenario.runtime.tick_timeout_s
        self._next_poll = 0.0  # when to next poll the child processes
        self._next_progress = 0.0

    def await_alive(self, inbox: Inbox) -> None:
        """Wait until every service has declared its liveliness token."""
        t0 = time.monotonic()
        deadline = t0 + self.start_timeout_s
        while not self.alive.issuperset(self.names):
            self._pump(inbox, deadline, "to start")
        self.observer.event(
            f"all {len(self.names)} services alive after {time.monotonic() - t0:.2f} s"
        )

    def _pump(self, inbox: Inbox, deadline: float, what: str) -> None:
        """Take one event; fail fast on a dead child or a timeout, naming the service."""
        self.stop.check()
        now = time.monotonic()
        # a dead service's liveliness token vanishes at once (TCP closes); polling the
        # processes as well catches one that never declared it, but need not run per event
        if now >= self._next_poll:
            self._next_poll = now + 0.2
            for name, child in self.sup.children.items():
                if name not in self.finished and child.proc.poll() is not None:
                    raise ServiceFailed(child.describe_exit())
        if now >= self._next_progress:
            self._next_progress = now + PROGRESS_EVERY_S
            self.observer.progress(self.t_us / 1e6)
        left = deadline - now
        if left <= 0:
            if what.startswith("ack"):
                missing = sorted(set(self.names) - set(self.acks.get(self._tick_no, {})))
            elif what.startswith("to start"):
                missing = sorted(set(self.names) - self.alive)
            else:
                missing = []
            who = f"{', '.join(missing)} " if missing else ""
            raise ServiceFailed(f"timed out after {self.timeout_s} s waiting for {who}{what}")
        ev = inbox.get(timeout=min(left, 0.2))
        if ev is None:
            return
        if isinstance(ev, Liveliness):
            if (alarm := self.claims.seen(ev.key, ev.alive)) is not None:
                self.observer.event(alarm)
            if self.keys.is_claim(ev.key):
                return
            service = ev.key.rsplit("/", 1)[-1]
            if ev.alive:
                self.alive.add(service)
            elif service in self.sup.children and service not in self.finished:
                child = self.sup.children[service]
                try:
                    child.proc.wait(timeout=2.0)
                except Exception:  # noqa: BLE001 - still report it as gone
                    pass
                raise ServiceFailed(f"{child.describe_exit()} (its liveliness token vanished)")
            return
        self._take(ev)

    def _take(self, ev: Received) -> None:
        acked_by = self.keys.acked_by(ev.key)
        if acked_by is not None or isinstance(ev.msg, TickAck):
            # an ack counts on its service's own key only; anything else there is ignored
            if not isinstance(ev.msg, TickAck) or ev.msg.service != acked_by:
                return
            ack = ev.msg
            # an older one is a late repeat, and a repeat of one taken carries nothing new
            if ack.tick >= self._tick_no and acked_by not in self.acks.get(ack.tick, {}):
                self.acks.setdefault(ack.tick, {})[acked_by] = ack
                self.hub.take(acked_by, ack.frames)
            if self.stopping:
                self.finished.add(acked_by)
            return
        if isinstance(ev.msg, Tick):
            return
        # nothing of the run's own is put on a stream key in lockstep (its frames travel in
        # acks): this is someone else's put, recorded only if it can be the stream's
        # publisher's (Record), and sent to no service
        service, stream = self.keys.split(ev.key)
        if self.record.add(service, stream, ev.msg) is None:  # not shown if refused
            self.observer.message(service, stream, ev.msg)

    def _send(
        self, pub: TickSender, k: int, t_us: int, to: list[str], *, stop: bool = False
    ) -> None:
        """Tick k at t_us to the services `to`, carrying every frame they read not sent them
        yet (FrameHub): one put, which Zenoh copies to each of them."""
        frames = () if stop else self.hub.for_tick(to)
        pub.put(
            Tick(stamp=t_us / 1e6, tick=k, time_us=t_us, due=tuple(to), stop=stop, frames=frames)
        )

    def _release(self, pub: TickSender, got: dict[str, TickAck]) -> None:
        """Send the held groups of the next tick whose feeders have all acked this one."""
        if not self.held:
            return
        ready = [h for h in self.held if all(f in got for f in h.feeders)]
        for h in ready:
            self.held.remove(h)
            self._send(pub, h.tick, h.time_us, list(h.services))

    def _tick(
        self,
        inbox: Inbox,
        pub: TickSender,
        k: int,
        t_us: int,
        due: list[str],
        *,
        need: dict[str, int] | None = None,
        sent: tuple[str, ...] = (),
        stop: bool = False,
    ) -> Done:
        """Run tick k: send it to the due services not `sent` it early, collect every due
        service's ack (and so its frames), judge the end. Given `need` (every service's next
        need before the tick; the caller's judgement that each due one's is known) it may
        start tick k+1 early (lookahead.py)."""
        self._tick_no = k
        self.stopping = stop
        self.t_us = t_us
        to = [n for n in due if n not in sent]
        if to:
            self._send(pub, k, t_us, to, stop=stop)
        deadline = time.monotonic() + self.timeout_s
        judged, end, ahead = False, None, None
        while True:
            got = self.acks.get(k, {})
            self._release(pub, got)
            running = [n for n in due if n not in got]
            if not running:
                break
            if need is not None and not judged and self.lookahead.predictable(running):
                # the end is judged on the frames of the services done (lookahead.py)
                judged, end = True, self.mission.observe(self.record)
                if end is None:
                    ahead = self._start_next(pub, k, t_us, need, dict(got), running)
                continue
            self._pump(inbox, deadline, f"acknowledging tick {k}")
        acks = self.acks.pop(k)
        for old in [t for t in self.acks if t < k]:
            del self.acks[old]
        if ahead is not None:
            for n, predicted in ahead.predicted.items():
                if acks[n].next_us != predicted or acks[n].wakes:
                    raise RuntimeError(
                        f"lockstep look-ahead: {n} acknowledged tick {k} needing t="
                        f"{acks[n].next_us} us (predicted {predicted}) and waking {acks[n].wakes}"
                    )
        if not judged and not stop:
            end = self.mission.observe(self.record)
        return Done(acks, end, ahead)

    def _start_next(
        self,
        pub: TickSender,
        k: int,
        t_us: int,
        need: dict[str, int],
        got: dict[str, TickAck],
        running: list[str],
    ) -> Ahead | None:
        """Send tick k+1 now to its services not running tick k that read none of the running
        ones; hold it for those that do until these have acked (lookahead.py)."""
        predicted = {n: t_us + self.lookahead.period_us[n] for n in running}
        after = dict(need) | {n: a.next_us for n, a in got.items()} | predicted
        for a in got.values():
            for receiver, at in a.wakes.items():
                after[receiver] = min(after[receiver], at)
        nxt = min(after.values())
        if nxt > self._max_us or nxt >= NEVER:
            return None
        waits = self.lookahead.waits([n for n in sorted(after) if after[n] <= nxt], running)
        if not waits:
            return None
        groups: dict[tuple[str, ...], list[str]] = {}
        for service, feeders in waits.items():
            groups.setdefault(feeders, []).append(service)
        for feeders, services in sorted(groups.items()):
            if feeders:
                self.held.append(Held(k + 1, nxt, tuple(services), feeders))
            else:
                self._send(pub, k + 1, nxt, services)
        self.started_early += 1
        return Ahead(nxt, tuple(sorted(waits)), predicted)

    def drive(self, inbox: Inbox, pub: TickSender, tap: WatchTap | None = None) -> RunResult:
        """Tick until the mission ends or max_time; a stop request raises Interrupted. Every
        frame recorded is handed to `tap` (the run's watch tap): no frame is put on its
        stream's key, where the tap would hear it."""
        self.hub.tap = tap
        max_us = self._max_us = round(self.mission.max_time_s * 1e6)
        k, t_us, reason = 0, 0, "max_time"
        # when each service next needs a tick: its own next event (from its last ack) or a
        # wake delivery someone sent it since (reported by the sender, before it arrives)
        need = dict.fromkeys(self.names, 0)
        stepped: set[str] = set()  # services that acknowledged a tick: their need is known
        sent: tuple[str, ...] = ()  # services tick k was sent to early
        wall0 = time.monotonic()
        self.observer.event("mission clock started (lockstep: virtual time)")
        while True:
            due = [n for n in sorted(need) if need[n] <= t_us]
            # a predictable service is due now for its step only once it has told its need
            # (before its first ack, every service is due at t = 0, its step maybe not)
            done = self._tick(
                inbox,
                pub,
                k,
                t_us,
                due,
                need=need if stepped.issuperset(due) else None,
                sent=sent,
            )
            stepped.update(due)
            for n in due:
                need[n] = done.acks[n].next_us
            for n in due:
                for receiver, at in done.acks[n].wakes.items():
                    need[receiver] = min(need[receiver], at)
            if done.end is not None:
                reason = done.end
                break
            nxt = min(need.values())
            if done.ahead is not None:
                now_due = [n for n in sorted(need) if need[n] <= nxt]
                if nxt != done.ahead.time_us or not set(done.ahead.services) <= set(now_due):
                    raise RuntimeError(
                        f"lockstep look-ahead: tick {k + 1} started at t={done.ahead.time_us} us "
                        f"for {done.ahead.services}, but it is at t={nxt} us for {now_due}"
                    )
            if nxt > max_us or nxt >= NEVER:
                break
            t_us, k = nxt, k + 1
            sent = done.ahead.services if done.ahead is not None else ()
        self._tick(inbox, pub, k + 1, t_us, sorted(need), stop=True)
        log.info(
            "lockstep run ended at t=%.3f s after %d ticks (%d started early) in %.2f s wall: %s",
            t_us / 1e6,
            k + 1,
            self.started_early,
            time.monotonic() - wall0,
            reason,
        )
        self.observer.event(f"mission ended at t={t_us / 1e6:.2f} s: {reason}")
        return RunResult(reason, t_us / 1e6, k + 1, self.record, self.mission.metrics(self.record))


def run_lockstep(scenario: Scenario, raw: JsonObject, log_dir: Path | None = None) -> RunResult:
    """Run a mission with every service in its own process; see the module docstring."""
    return run_locally(scenario, raw, log_dir, SERVICE_MODULE, Coordinator)
