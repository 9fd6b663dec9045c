"""The lockstep runtime: one OS process per service over Zenoh, virtual time from a coordinator.

The coordinator (this process) is also the Zenoh router the services connect to as clients,
and the recorder of everything they publish. Tick k at time T carries the watermarks (last seq
of every stream published before tick k); each service first waits until it holds every input
message up to those watermarks, then runs the tick exactly as the inproc runtime does and
acknowledges with what it published and when it next needs a tick. Time jumps to the earliest
such need. Because the hosts, link models and delivery order are the same, the trajectory is
bit-identical to an inproc run of the same scenario and seed.
"""

from __future__ import annotations

import json
import logging
import tempfile
import time
from pathlib import Path
from typing import Any

from common.bus import Bus, Inbox, Keys, Liveliness, Received
from common.config.bus import BusConfig
from common.config.scenario import Scenario
from common.messages import Tick, TickAck
from common.runtime.forked import warm_up
from common.runtime.host import NEVER
from common.runtime.inproc import RunResult
from common.runtime.mission import load_mission
from common.runtime.procs import Child, connectable, fork, free_port, stop_all
from common.runtime.record import Record
from common.runtime.service_process import CLOCK
from common.runtime.ticks import TickSender

log = logging.getLogger("tidelink.lockstep")


class ServiceFailed(RuntimeError):
    """A service process died or stopped answering; the message names it."""


class Coordinator:
    """Starts the service processes, drives the ticks, records the run."""

    service_module = "common.runtime.lockstep_service"

    def __init__(self, scenario: Scenario, raw: dict[str, Any], log_dir: Path) -> None:
        self.scenario = scenario
        self.raw = raw
        self.mission = load_mission(scenario)
        self.keys = Keys(scenario.run.name, scenario.run.vehicle)
        self.log_dir = log_dir
        self.record = Record()
        self.children: dict[str, Child] = {}
        self.acks: dict[str, TickAck] = {}
        self.alive: set[str] = set()
        self.finished: set[str] = set()  # services that acknowledged the stop tick
        self._next_poll = 0.0  # when to next poll the child processes
        self.stopping = False
        self.timeout_s = scenario.runtime.tick_timeout_s

    def run(self) -> RunResult:
        warm_up()  # the fork server imports the services while we open the router
        # [bus] listen: a fixed endpoint lets monitors on other machines join the run
        listen = self.scenario.bus.listen or (f"tcp/127.0.0.1:{free_port()}",)
        endpoint = connectable(listen[0])
        with tempfile.TemporaryDirectory(prefix="tidelink-") as tmp:
            raw_path = Path(tmp) / "scenario.json"
            raw_path.write_text(json.dumps(self.raw))
            bus_cfg = BusConfig(
                mode="router",
                listen=listen,
                multicast_scouting=self.scenario.bus.multicast_scouting,
            )
            with Bus(bus_cfg, self.keys) as bus:
                inbox = Inbox()
                bus.subscribe(self.keys.all_streams, inbox)
                bus.watch_alive(inbox)
                tick_pub = TickSender(bus, self.mission.names)
                bus.declare_alive(CLOCK)
                try:
                    for name in self.mission.names:
                        self.children[name] = fork(
                            name,
                            self.service_module,
                            [name, "--scenario-json", str(raw_path), "--connect", endpoint],
                            self.log_dir,
                        )
                    t_spawn = time.monotonic()
                    self._await_alive(inbox)
                    log.info(
                        "all %d services alive after %.2f s",
                        len(self.children),
                        time.monotonic() - t_spawn,
                    )
                    result = self.drive(inbox, tick_pub)
                except BaseException:
                    stop_all(list(self.children.values()))
                    raise
            # the bus is closed: our token vanished, which releases the services
            t_close = time.monotonic()
            for child in self.children.values():
                try:
                    child.proc.wait(timeout=10.0)
                except Exception:  # noqa: BLE001 - stop_all below makes sure
                    log.warning("%s did not exit after the run; stopping it", child.name)
            stop_all(list(self.children.values()))
            log.info("services exited %.2f s after the run", time.monotonic() - t_close)
            return result

    def _await_alive(self, inbox: Inbox) -> None:
        deadline = time.monotonic() + self.scenario.runtime.start_timeout_s
        while not self.alive.issuperset(self.mission.names):
            self._pump(inbox, deadline, "to start")

    def _pump(self, inbox: Inbox, deadline: float, what: str) -> None:
        """Take one event; fail fast on a dead child or a timeout, naming the service."""
        now = time.monotonic()
        # a dead service's liveliness token vanishes at once (TCP closes); polling the
        # processes as well catches one that never declared it, but need not run per event
        if now >= self._next_poll:
            self._next_poll = now + 0.2
            for name, child in self.children.items():
                if name not in self.finished and child.proc.poll() is not None:
                    raise ServiceFailed(child.describe_exit())
        left = deadline - now
        if left <= 0:
            if what.startswith("ack"):
                missing = sorted(set(self.mission.names) - set(self.acks))
            elif what.startswith("to start"):
                missing = sorted(set(self.mission.names) - self.alive)
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
            elif service in self.children and service not in self.finished:
                child = self.children[service]
                try:
                    child.proc.wait(timeout=2.0)
                except Exception:  # noqa: BLE001 - still report it as gone
                    pass
                raise ServiceFailed(f"{child.describe_exit()} (its liveliness token vanished)")
            return
        self._on_message(ev)

    def _on_message(self, ev: Received) -> None:
        if isinstance(ev.msg, TickAck):
            self.acks[ev.msg.service] = ev.msg
            if self.stopping:
                self.finished.add(ev.msg.service)
            return
        if isinstance(ev.msg, Tick):
            return
        service, stream = self.keys.split(ev.key)
        self.record.add(service, stream, ev.msg)

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
        max_us = round(self.mission.max_time_s * 1e6)
        k, t_us, reason = 0, 0, "max_time"
        marks: dict[str, int] = {}
        # when each service next needs a tick: its own next event (from its last ack) or a
        # wake delivery someone sent it since (reported by the sender, before it arrives)
        need = {n: 0 for n in self.mission.names}
        wall0 = time.monotonic()
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
        log.info(
            "lockstep run ended at t=%.3f s after %d ticks in %.2f s wall: %s",
            t_us / 1e6,
            k + 1,
            time.monotonic() - wall0,
            reason,
        )
        return RunResult(reason, t_us / 1e6, k + 1, self.record, self.mission.metrics(self.record))


def run_lockstep(scenario: Scenario, raw: dict[str, Any], log_dir: Path | None = None) -> RunResult:
    """Run a mission with every service in its own process; see the module docstring."""
    if log_dir is None:
        log_dir = Path(tempfile.mkdtemp(prefix="tidelink-logs-"))
    return Coordinator(scenario, raw, log_dir).run()
