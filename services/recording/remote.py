"""The remote recorder (`tidelink record`): a run's watch copies, through a Watcher, to MCAP.

It waits for a run (its clock's liveliness token or a tapped frame), asks the run for its
scenario and for the newest frame of every stream (so a late start still has the path in
force, the tracks, the vehicle's mode), then writes every copy it gets until the run's
RunEnd, the clock's token vanishing, or a stop request. The copies are published DROP: a
recorder that cannot keep up loses some, and the seq gaps say how many (SeqGaps). A recorder
that stops (Ctrl-C) asks the run for its newest frames and counts those it never got as lost
too; one that never got the run's end (frozen past it, cut off from the router) still ends,
and says that what the run sent after its last frame is lost, in an unknown number.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from common.bus import CLOCK, Bus, Keys, Liveliness
from common.bus.gaps import SeqGaps
from common.bus.keys import END
from common.bus.watcher import END_GRACE_S, WatchedFrame, Watcher
from common.config.scenario import Scenario, scenario_from_raw
from common.jsonsafe import JsonObject
from common.messages import RunEnd, WireError, decode
from common.runtime.processes.children import wait_for_endpoint
from common.runtime.processes.signals import StopRequest
from common.view import View
from services.recording.layout import stream_name, stream_types
from services.recording.writer import RunInfo, RunWriter

POLL_S = 0.2  # how often the loop looks at the stop request when nothing arrives
SAY_WAITING_AFTER_S = 1.0  # say "no run yet" once nothing was heard for this long
# nothing heard for this long: ask whether the run's clock is still there (a recorder whose
# session the router closed hears no token vanish once it reconnects)
QUIET_CHECK_S = 2.0
# cut off from the router for this long (its lease is 10 s): the run, or its router, is gone
CUT_OFF_S = 12.0


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
    # the run's RunEnd reached the recorder, or it was stopped (then its newest frames were
    # asked for, and the ones it never got are counted lost); False: what the run sent after
    # the last frame here is lost too, in a number nobody here knows
    complete: bool = True
    last_stamp_s: float | None = None  # mission time of the newest frame recorded


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
        self.complete = True
        self.last_stamp: float | None = None
        self.bus = bus

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
            complete=self.complete,
            last_stamp_s=self.last_stamp,
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

    def _scenario(self, keys: Keys) -> JsonObject | None:
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
        heard_at = cut_at = time.monotonic()
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
            now = time.monotonic()
            if self.stop.requested:
                self._count_behind(keys)
                return f"stopped by {self.stop.signal_name}"
            if self.bus.connected():
                cut_at = now
            elif now - cut_at > CUT_OFF_S:
                self.complete = False
                return f"cut off from the router for {CUT_OFF_S:g} s; the run's end never came"
            elif now - cut_at > END_GRACE_S and not self._router_listens():
                self.complete = False  # the launch's router went with its run
                return "the run's router left without a RunEnd reaching the recorder"
            if self.gone_at is None and now - heard_at > QUIET_CHECK_S and self.bus.connected():
                heard_at = now
                if CLOCK not in self.watcher.alive(keys):
                    self.gone_at = now  # its token went while this session was away
            if self.gone_at is not None and now - self.gone_at > END_GRACE_S:
                if not self.bus.connected():
                    pass  # back on the router, or cut off for good: decided above
                elif CLOCK in self.watcher.alive(keys):
                    self.gone_at = None  # it was this session that had gone, not the run
                    self.say("back on the router; the run goes on (frames meanwhile are lost)")
                else:
                    self.complete = False
                    return "the run's clock left without a RunEnd reaching the recorder"
            new = self.watcher.get(POLL_S)
            if new is not None:
                heard_at = time.monotonic()
                self.heard.append(new)

    def _router_listens(self) -> bool:
        return any(wait_for_endpoint(ep, 0.0) for ep in self.bus.cfg.connect)

    def _count_behind(self, keys: Keys) -> None:
        """Stopped while the run goes on: the run's newest frames say how many it had sent
        that never reached this recorder (a recorder frozen for a while missed many)."""
        if not self.bus.connected():
            return
        for f in self.watcher.latest(keys, timeout_s=0.5):
            seq = _seq(f.payload)
            if seq is not None and (f.run, f.vehicle) == (keys.run, keys.vehicle):
                self.gaps.behind(stream_name(f.service, f.stream), seq)

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
            if msg is not None and not isinstance(msg, RunEnd):
                self.last_stamp = max(self.last_stamp or 0.0, msg.stamp)
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
