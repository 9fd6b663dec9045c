"""The lockstep coordinator as the hub of its run's frames (lockstep.py).

A lockstep service puts nothing on its stream keys: it acknowledges a tick with the frames it
published in it (Frame: the message's bytes and its routing attachment). The hub records each
one, hands it to the run's watch tap (which would otherwise have heard it on its stream key),
and queues it for every service that reads its stream, until that service's next tick carries
it. A service so holds everything sent to it before a tick when it runs it, and is woken by
nothing but its ticks.
"""

from __future__ import annotations

import logging
from collections.abc import Iterable

from common.bus.tap import WatchTap
from common.messages import Frame, WireError, decode
from common.runtime.distributed.observer import RunObserver
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.record import Record

log = logging.getLogger("tidelink.lockstep")


class FrameHub:
    """Records the frames acknowledged, and holds each for its readers' next tick."""

    def __init__(self, flow: Dataflow, record: Record, observer: RunObserver) -> None:
        self.record = record
        self.observer = observer
        self.tap: WatchTap | None = None  # the run's watch tap, once the run is driven
        self._readers = {key: tuple(r for r, _ in rs) for key, rs in flow.receivers.items()}
        self._queued: dict[str, list[Frame]] = {n: [] for n in flow.names}

    def take(self, service: str, frames: Iterable[Frame]) -> None:
        """The frames `service` acknowledged (in publishing order): record them, show them to
        the tap, queue each for the services that read it."""
        for f in frames:
            if f.source != service:
                continue  # an ack carries its own service's frames only
            try:
                msg = decode(f.data)
            except WireError as exc:  # its own host encoded it: a bug, not the network
                log.error("%s acknowledged an undecodable frame on %s: %s", service, f.stream, exc)
                continue
            if self.record.add(service, f.stream, msg) is None:  # not shown if refused
                self.observer.message(service, f.stream, msg)
            if self.tap is not None:
                self.tap.feed(service, f.stream, f.data, f.routing)
            for reader in self._readers.get((service, f.stream), ()):
                self._queued[reader].append(f)

    def for_tick(self, services: Iterable[str]) -> tuple[Frame, ...]:
        """Every frame queued for these services, once each (two of them may read one), in
        the order taken; their queues are emptied."""
        frames: list[Frame] = []
        seen: set[int] = set()
        for n in services:
            for f in self._queued[n]:
                if id(f) not in seen:
                    seen.add(id(f))
                    frames.append(f)
            self._queued[n] = []
        return tuple(frames)
