"""The lockstep runtime: one OS process per service over Zenoh, virtual time from a coordinator.

The coordinator is the clock and the recorder of everything the services publish. Tick k at
time T carries the watermarks (last seq of every stream published before tick k); each service
first waits until it holds every input message up to those watermarks, then runs the tick
exactly as the inproc runtime does and acknowledges with what it published and when it next
needs a tick. Time jumps to the earliest such need. Because the hosts, link models and
delivery order are the same, the trajectory is bit-identical to an inproc run of the same
scenario and seed. `run_lockstep` makes this process the Zenoh router and forks the services;
the launcher drives the same Coordinator with its own router and supervised processes.
"""

from __future__ import annotations

import logging
import time
from pathlib import Path
from typing import Any

from common.bus import Inbox, Liveliness, Received
from common.config.scenario import Scenario
from common.messages import Tick, TickAck
from common.runtime.distributed.bringup import run_locally
from common.runtime.distributed.observer import RunContext
from common.runtime.distributed.ticks import TickSender
from common.runtime.model.host import NEVER
from common.runtime.model.mission import mission_record
from common.runtime.model.result import RunResult
from common.runtime.processes.supervisor import ServiceFailed

SERVICE_MODULE = "common.runtime.distributed.lockstep_service"
PROGRESS_EVERY_S = 0.25  # wall seconds between progress reports to the observer


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
        self.acks: dict[str, TickAck] = {}
        self.alive: set[str] = set()
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
                missing = sorted(set(self.names) - set(self.acks))
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
        if isinstance(ev.msg, TickAck):
            self.acks[ev.msg.service] = ev.msg
            if self.stopping:
                self.finished.add(ev.msg.service)
            return
        if isinstance(ev.msg, Tick):
            return
        service, stream = self.keys.split(ev.key)
        if self.record.add(service, stream, ev.msg) is None:  # not shown if refused
            self.observer.message(service, stream, ev.msg)

    def _tick(
        self,
        inbox: Inbox,
        pub: TickSender,
        k: int,
        t_us: int,
        marks: dict[str, int],
        due: list[str],
        stop: bool = False,
    ) -> dict[str, int]:
        self.acks = {}
        self.stopping = stop
        self.t_us = t_us
        pub.put(
            Tick(
                stamp=t_us / 1e6, tick=k, time_us=t_us, watermarks=marks, due=tuple(due), stop=stop
            )
        )
        deadline = time.monotonic() + self.timeout_s
        while any(self.acks.get(n) is None or self.acks[n].tick != k for n in due):
            self._pump(inbox, deadline, f"acknowledging tick {k}")
        new_marks = dict(marks)
        for a in self.acks.values():
            new_marks.update(a.published)
        while missing := self.record.missing(new_marks):
            self._pump(inbox, deadline, f"data of tick {k} on {', '.join(missing)}")
        return new_marks

    def drive(self, inbox: Inbox, pub: TickSender) -> RunResult:
        """Tick until the mission ends or max_time; a stop request raises Interrupted."""
        max_us = round(self.mission.max_time_s * 1e6)
        k, t_us, reason = 0, 0, "max_time"
        marks: dict[str, int] = {}
        # when each service next needs a tick: its own next event (from its last ack) or a
        # wake delivery someone sent it since (reported by the sender, before it arrives)
        need = dict.fromkeys(self.names, 0)
        wall0 = time.monotonic()
        self.observer.event("mission clock started (lockstep: virtual time)")
        while True:
            due = [n for n in sorted(need) if need[n] <= t_us]
            marks = self._tick(inbox, pub, k, t_us, marks, due)
            for n in due:
                need[n] = self.acks[n].next_us
            for n in due:
                for receiver, at in self.acks[n].wakes.items():
                    need[receiver] = min(need[receiver], at)
            end = self.mission.observe(self.record)
            if end is not None:
                reason = end
                break
            nxt = min(need.values())
            if nxt > max_us or nxt >= NEVER:
                break
            t_us, k = nxt, k + 1
        self._tick(inbox, pub, k + 1, t_us, marks, sorted(need), stop=True)
        logging.getLogger("tidelink.lockstep").info(
            "lockstep run ended at t=%.3f s after %d ticks in %.2f s wall: %s",
            t_us / 1e6,
            k + 1,
            time.monotonic() - wall0,
            reason,
        )
        self.observer.event(f"mission ended at t={t_us / 1e6:.2f} s: {reason}")
        return RunResult(reason, t_us / 1e6, k + 1, self.record, self.mission.metrics(self.record))


def run_lockstep(scenario: Scenario, raw: dict[str, Any], log_dir: Path | None = None) -> RunResult:
    """Run a mission with every service in its own process; see the module docstring."""
    return run_locally(scenario, raw, log_dir, SERVICE_MODULE, Coordinator)
