"""What a run's driver is given: the run, its local processes, and hooks (passed in)."""

from __future__ import annotations

import logging
from dataclasses import dataclass, field
from typing import Protocol

from common.bus import Inbox, Keys
from common.bus.tap import WatchTap
from common.config.scenario import Scenario
from common.messages import Message
from common.runtime.distributed.ticks import TickSender
from common.runtime.model.mission import Mission
from common.runtime.model.record import Record
from common.runtime.model.result import RunResult
from common.runtime.processes.signals import StopRequest
from common.runtime.processes.supervisor import Supervisor

log = logging.getLogger("tidelink.run")


class RunObserver(Protocol):
    """What a driver (lockstep coordinator, realtime driver) tells whoever watches the run."""

    def event(self, text: str) -> None:
        """Something worth a line: services up, clock started, a service gone, the end."""

    def message(self, service: str, stream: str, msg: Message) -> None:
        """Every message recorded, as it is recorded."""

    def progress(self, t_s: float) -> None:
        """The mission time now (called a few times a second at most)."""


class LogObserver:
    """The default observer: events go to the log; messages and progress are not shown."""

    def event(self, text: str) -> None:
        log.info("%s", text)

    def message(self, service: str, stream: str, msg: Message) -> None:
        return None

    def progress(self, t_s: float) -> None:
        return None


@dataclass(frozen=True, kw_only=True)
class RunContext:
    """A driver's inputs: the scenario and its mission, the run's keys, the processes started
    here (`sup`; a remote service has none), who watches, and the stop request to honour."""

    scenario: Scenario
    mission: Mission
    keys: Keys
    sup: Supervisor
    observer: RunObserver = field(default_factory=LogObserver)
    stop: StopRequest = field(default_factory=StopRequest)


class Driver(Protocol):
    """A run's driver (lockstep Coordinator, RealtimeDriver): made from a RunContext."""

    mission: Mission
    observer: RunObserver
    record: Record

    def await_alive(self, inbox: Inbox) -> None:
        """Wait until every service has declared its liveliness token."""

    def drive(self, inbox: Inbox, pub: TickSender, tap: WatchTap) -> RunResult:
        """Run the mission clock until the mission ends, max_time or a stop request; frames
        recorded that were not put on their stream keys (lockstep) are handed to `tap`."""
