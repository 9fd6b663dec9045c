"""The remote recorder (`tidelink record`): a run's watch copies, through a Watcher, to MCAP.

It waits for a run (its clock's liveliness token or a tapped frame), asks the run for its
scenario and for the newest frame of every stream (so a late start still has the path in
force, the tracks, the vehicle's mode), then writes every copy it gets until the run's
RunEnd, the clock's token vanishing, or a stop request. The copies are published DROP: a
recorder that cannot keep up loses some, and the seq gaps say how many (SeqGaps).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common.bus import CLOCK, Bus, Keys, Liveliness
from common.bus.keys import END
from common.bus.watcher import END_GRACE_S, WatchedFrame, Watcher
from common.config.scenario import Scenario, scenario_from_raw
from common.messages import RunEnd, WireError, decode
from common.runtime.processes.signals import StopRequest
from common.view import View
from services.recording.gaps import SeqGaps
from services.recording.layout import stream_name, stream_types
from services.recording.writer import RunInfo, RunWriter

POLL_S = 0.2  # how often the loop looks at the stop request when nothing arrives
SAY_WAITING_AFTER_S = 1.0  # say "no run yet" once nothing was heard for this long


@dataclass(frozen=True)
class RecordOutcome:
    """What a remote recording got: per stream frames and losses, and how it ended."""

    path: Path
    run: str
    vehicle: str
    counts: dict[str, int]  # frames written per 'service/stream'
    gaps: SeqGaps
    ended: str
    size_bytes: int


class RemoteRecorder:
    """Records one run seen through `bus` (a client of the run's router) to `path`."""

    def __init__(
        self,
        bus: Bus,
        path: Path,
        *,
        run: str | None,
        vehicle: str | None,
        stop: StopRequest,
        say: Callable[[str], None],
        view_for: Callable[[Scenario], View | None] = lambda s: None,
    ) -> None:
        self.path = path
        self.stop = stop
        self.say = say
        self.view_for = view_for
        self.watcher = Watcher(bus, run, vehicle)
        self.heard: list[WatchedFrame | Liveliness] = []  # before the writer is open
        self.gone_at: float | None = None  # when the run's clock token vanished
        self.gaps = SeqGaps()

    def record(self) -> RecordOutcome | None:
        """Record the first run that shows up; None if stopped before one did."""
        self.watcher.start()
        keys = self._find_run()
        if keys is None:
            return None
        raw = self._scenario(keys)
        if raw is None:
            return None
        scenario = scenario_from_raw(raw, f"the scenario of run {keys.run}")
        info = RunInfo(run=keys.run, vehicle=keys.vehicle, scenario_raw=raw, recorder="record")
        writer = RunWriter(self.path, info, stream_types(scenario), view=self.view_for(scenario))
        self.say(f"recording run {keys.run}/{keys.vehicle} to {self.path}")
        try:
            ended = self._write(keys, writer)
        finally:
            writer.close()
        return RecordOutcome(
            path=self.path,
            run=keys.run,
            vehicle=keys.vehicle,
            counts=dict(writer.counts),
            gaps=self.gaps,
            ended=ended,
            size_bytes=self.path.stat().st_size,
        )

    def _find_run(self) -> Keys | None:
        """The run of the first clock token or tapped frame heard (others are ignored)."""
        t0 = time.monotonic()
        said = False
        while not self.stop.requested:
            ev = self.watcher.get(POLL_S)
            if ev is None:
                if not said and time.monotonic() - t0 > SAY_WAITING_AFTER_S:
                    self.say("no run yet; waiting for one (Ctrl-C to stop)")
                    said = True
                continue
            self.heard.append(ev)
            if isinstance(ev, WatchedFrame):
                return Keys(ev.run, ev.vehicle)
            run, vehicle, service = Keys.parse_alive(ev.key)
            if service == CLOCK and ev.alive:
                return Keys(run, vehicle)
        return None

    def _scenario(self, keys: Keys) -> dict[str, Any] | None:
        """The run's scenario, asked until it answers (its tap serves it)."""
        said = False
        while not self.stop.requested:
            raw = self.watcher.scenario(keys)
            if raw is not None:
                return raw
            if not said:
                self.say(f"run {keys.run}/{keys.vehicle} does not answer for its scenario yet")
                said = True
        return None

    def _write(self, keys: Keys, writer: RunWriter) -> str:
        """Write the newest frame of every stream (asked for: a late start still gets the path
        in force, the tracks, the vehicle's mode), then every copy heard, until the run ends;
        returns how it ended.

        The answers to the query are written but not counted for gaps: only the copies come
        in each stream's order. A copy of a frame the query already gave is counted, not
        written again (the tap's running count `n` names each frame).
        """
        asked = self.watcher.latest(keys)
        from_query = {f.n for f in asked}
        for f in asked:
            self._frame(f, keys, writer, write=True, count=False)
        while True:
            for ev in self.heard:
                if isinstance(ev, Liveliness):
                    self._alive(ev, keys, writer)
                    continue
                ended = self._frame(ev, keys, writer, write=ev.n not in from_query)
                if ended is not None:
                    return ended
            self.heard = []
            writer.flush_if_due()
            if self.stop.requested:
                return f"stopped by {self.stop.signal_name}"
            if self.gone_at is not None and time.monotonic() - self.gone_at > END_GRACE_S:
                return "the run's clock left without a RunEnd reaching the recorder"
            new = self.watcher.get(POLL_S)
            if new is not None:
                self.heard.append(new)

    def _alive(self, ev: Liveliness, keys: Keys, writer: RunWriter) -> None:
        run, vehicle, service = Keys.parse_alive(ev.key)
        if (run, vehicle) == (keys.run, keys.vehicle):
            writer.alive(service, ev.alive, time.time())
            if service == CLOCK and not ev.alive:
                self.gone_at = time.monotonic()

    def _frame(
        self,
        f: WatchedFrame,
        keys: Keys,
        writer: RunWriter,
        *,
        write: bool,
        count: bool = True,
    ) -> str | None:
        """Write and/or count one frame of the run; how the run ended if it is the RunEnd."""
        if (f.run, f.vehicle) != (keys.run, keys.vehicle):
            return None
        if write:
            msg = writer.frame(f.service, f.stream, f.payload, f.attachment, f.wall)
        else:
            msg = None
        if count:
            seq = msg.seq if msg is not None else _seq(f.payload)
            if seq is not None:
                self.gaps.see(stream_name(f.service, f.stream), seq)
        if write and (f.service, f.stream) == (CLOCK, END) and isinstance(msg, RunEnd):
            return f"{msg.reason} at t={msg.stamp:.2f} s"
        return None


def _seq(payload: bytes) -> int | None:
    try:
        return decode(payload).seq
    except WireError:
        return None
