"""`tidelink monitor`'s loop: find the runs on a router, join each (scenario and latest state),
poll their latest state at the view's rate (or follow every tapped frame), and hand snapshots
and events to a view (terminal dashboard or JSON lines)."""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from typing import Protocol

from common.bus import Bus, Keys, Liveliness
from common.bus.keys import CLOCK, END
from common.bus.watcher import WatchedFrame, Watcher
from common.config.bus import WatchTarget, client_config
from common.config.scenario import scenario_from_raw
from common.jsonsafe import JsonObject
from common.messages import Message, WireError, decode
from common.runtime.model.dataflow import read_description
from common.runtime.processes.children import wait_for_endpoint
from common.runtime.processes.signals import StopRequest
from services.monitor.state import EVENT_TYPES, STATE_TYPES, Event, RunState

log = logging.getLogger("tidelink.monitor")

ROUTER_PROBE_S = 0.5  # a router that is not there is probed this often
ROUTER_CHECK_S = 1.0  # while no run is on, whether the router is still there
DISCOVERY_S = 1.0  # liveliness history answers in ms; past this, there is no run to watch
EXIT_NO_RUN = 2
# --rate: the streams of STATE_TYPES at the rate, every other stream every FULL_POLL_S, in a
# poll of its own once the state was shown (its larger reply must not hold up the state's on
# a thin link; docs/notes/0003-monitor-polls-by-default.md). Polling by default, the monitor
# still hears every frame of EVENT_TYPES (a few messages a second).
FULL_POLL_S = 2.0


@dataclass(frozen=True, kw_only=True)
class MonitorOptions(WatchTarget):
    """What to watch and how. By default the monitor polls each run's latest state once per
    update (decimated at the run: the vehicle's state streams each time, every stream every
    FULL_POLL_S) and hears every frame of the streams that carry events (EVENT_TYPES);
    `rate_hz` sets the poll rate and drops those subscriptions too (thin links: nothing but
    the polls crosses the link); `every_frame` receives every tapped frame instead."""

    follow: bool = False
    rate_hz: float | None = None
    every_frame: bool = False
    update_s: float = 0.5  # how often snapshots go to the view
    stale_s: float = 2.0  # a stream older than this raises an alarm
    no_wait: bool = False

    def __post_init__(self) -> None:
        if self.rate_hz is not None and not self.rate_hz > 0:
            raise ValueError(f"--rate: {self.rate_hz!r} must be > 0 (Hz)")
        if self.rate_hz is not None and self.every_frame:
            raise ValueError("--rate and --all exclude each other (poll, or every frame)")
        if not self.update_s > 0:
            raise ValueError(f"update period {self.update_s!r} must be > 0 (s)")
        if not self.stale_s > 0:
            raise ValueError(f"--stale: {self.stale_s!r} must be > 0 (s)")


@dataclass
class PollMarks:
    """--rate bookkeeping of one run: the tap counts polled up to, which streams are state."""

    after_state: int = 0  # the tap count the last poll of the state streams reached
    after_all: int = 0  # the tap count the last poll of every other stream reached
    next_full: float = 0.0  # monotonic time of the next poll of every other stream
    state_streams: set[str] = field(default_factory=set)  # "<service>/<stream>"
    followed: set[str] = field(default_factory=set)  # event streams subscribed to
    newest: dict[str, int] = field(default_factory=dict)  # stream -> tap count shown

    def take(self, f: WatchedFrame) -> bool:
        """True for a frame newer than the newest shown of its stream (polls overlap)."""
        name = f"{f.service}/{f.stream}"
        if f.n <= self.newest.get(name, 0):
            return False
        self.newest[name] = f.n
        return True


def _event_streams(reply: JsonObject | None) -> list[tuple[str, str]]:
    """(service, stream) of every output the run declares with an event type (EVENT_TYPES);
    none if the run did not answer, or not with a description (then they are followed once a
    poll shows them)."""
    try:
        described = read_description(reply or {"services": [], "links": []})
    except ValueError as exc:
        log.warning("the run's dataflow is not one this monitor reads: %s", exc)
        return []
    names = {t.__name__ for t in EVENT_TYPES}
    return [
        (svc["name"], out["stream"])
        for svc in described["services"]
        for out in svc["outputs"]
        if out["type"] in names
    ]


class MonitorView(Protocol):
    """Where a monitor's output goes."""

    def notice(self, text: str) -> None:
        """A line about the monitor itself (waiting for a run, joined one)."""

    def event(self, state: RunState, ev: Event) -> None: ...

    def update(self, states: list[RunState], now: float) -> None: ...

    def close(self) -> None: ...


class Monitor:
    """Watches the runs on one router until they end (or forever with `follow`)."""

    def __init__(self, opts: MonitorOptions, view: MonitorView, stop: StopRequest) -> None:
        self.opts = opts
        self.view = view
        self.stop = stop
        self.runs: dict[tuple[str, str], RunState] = {}
        self._polls: dict[tuple[str, str], PollMarks] = {}  # --rate: per run
        self._ended: set[tuple[str, str]] = set()  # --follow: runs shown to their end
        self.watched_any = False

    def run(self) -> int:
        """Watch; returns the exit status (0: the watched runs ended; 2: none and --no-wait).

        Each `tidelink launch` brings its own router: without one the monitor waits for it
        (with --no-wait it fails at once, naming the endpoint), and with --follow it opens a
        new session when the router it watched goes and the next one listens."""
        try:
            while not self.stop.requested:
                if not self.opts.no_wait and not self._router_up():
                    self.view.notice(f"no router at {self.opts.connect} yet; waiting")
                    while not self._router_up():
                        if self.stop.requested:
                            return 0
                cfg = client_config(self.opts.connect, self.opts.certs)
                try:
                    with Bus(cfg, Keys("monitor", "monitor"), identity=self.opts.identity) as bus:
                        watcher = Watcher(bus, self.opts.run, self.opts.vehicle)
                        watcher.start(frames=self.opts.every_frame)
                        code = self._loop(watcher)
                except ConnectionError as exc:
                    if self.opts.no_wait:
                        raise
                    # gone between the probe and Zenoh's connect: probe again
                    log.info("%s; trying again", exc)
                    continue
                if code is not None:
                    return code
                self.view.notice(f"the router at {self.opts.connect} is gone; waiting for the next")
            return 0
        finally:
            self.view.close()

    def _router_up(self) -> bool:
        """Whether the router accepts connections, probing for up to ROUTER_PROBE_S."""
        return wait_for_endpoint(self.opts.connect, ROUTER_PROBE_S)

    def _loop(self, watcher: Watcher) -> int | None:
        """Watch on one session; the exit status, or None when the router went (--follow)."""
        t0 = time.monotonic()
        told_waiting = False
        period = self.opts.update_s
        if self.opts.rate_hz is not None:
            period = 1.0 / self.opts.rate_hz
        next_update = next_probe = time.monotonic()
        while not self.stop.requested:
            ev = watcher.get(timeout=max(0.0, next_update - time.monotonic()))
            if ev is not None:
                self._take(watcher, ev)
                if time.monotonic() < next_update:
                    continue
            next_update = time.monotonic() + period
            if not self.opts.every_frame:
                self._poll(watcher)
            now = time.time()
            live = list(self.runs.values())
            for s in live:
                s.alarms(now)  # raise and clear alarms before their events are drained
                self._drain(s)
            if live:
                self.view.update(live, now)
            if not self.opts.every_frame:
                self._poll_others_due(watcher)
            if self.opts.follow:
                self._forget_ended()
            elif self.runs and all(s.over(now) for s in self.runs.values()):
                return 0
            if self.runs:
                continue
            if time.monotonic() - t0 >= DISCOVERY_S and not told_waiting:
                where = self._which()
                if self.opts.no_wait:
                    self.view.notice(f"no run {where} on {self.opts.connect}")
                    return EXIT_NO_RUN
                self.view.notice(f"no run {where} on {self.opts.connect} yet; waiting")
                told_waiting = True
            if time.monotonic() >= next_probe:  # no run on: is the router still there?
                next_probe = time.monotonic() + ROUTER_CHECK_S
                if not wait_for_endpoint(self.opts.connect, 0.0):
                    return None
        return 0

    def _which(self) -> str:
        if self.opts.run is None:
            return "at all" if self.opts.vehicle is None else f"with vehicle {self.opts.vehicle}"
        return f"{self.opts.run}" + (f"/{self.opts.vehicle}" if self.opts.vehicle else "")

    def _state(self, watcher: Watcher, run: str, vehicle: str) -> RunState:
        """The state of a run, joining it (scenario + latest frames) when first heard of."""
        key = (run, vehicle)
        state = self.runs.get(key)
        if state is not None:
            return state
        state = self.runs[key] = RunState(run, vehicle, stale_s=self.opts.stale_s)
        self.watched_any = True
        t_join = time.monotonic()
        keys = Keys(run, vehicle)
        raw = watcher.scenario(keys)
        if raw is not None:
            try:
                state.scenario = scenario_from_raw(raw)
            except Exception as exc:  # noqa: BLE001 - a bad scenario must not end the monitor
                log.warning("run %s/%s: its scenario does not load here: %s", run, vehicle, exc)
        marks = self._polls[key] = PollMarks(next_full=time.monotonic() + FULL_POLL_S)
        if self._follow_events:
            # subscribe before asking for the latest frames: nothing falls in between
            for service, stream in [(CLOCK, END), *_event_streams(watcher.dataflow(keys))]:
                self._follow(watcher, marks, keys, service, stream)
        # the tokens present now: the first update names every live service, not only the one
        # whose token made this run known (the others' events may still be queued)
        for service in watcher.alive(keys):
            state.liveliness(service, True, time.time())
        latest = watcher.latest(keys)
        for f in latest:
            self._polled(watcher, state, marks, f)
        marks.after_state = marks.after_all = max((f.n for f in latest), default=0)
        joined_in = time.monotonic() - t_join
        state._event(
            time.time(),
            "joined",
            f"joined {run}/{vehicle}: {len(latest)} latest frames in {joined_in * 1e3:.0f} ms",
            {
                "joined_in_s": round(joined_in, 4),
                "latest_frames": len(latest),
                "path_id": None if state.path is None else state.path.path_id,
                "scenario": raw is not None,
            },
        )
        return state

    def _take(self, watcher: Watcher, ev: WatchedFrame | Liveliness) -> None:
        if isinstance(ev, Liveliness):
            try:
                run, vehicle, service = Keys.parse_alive(ev.key)
            except ValueError:
                return
            if service == CLOCK and ev.alive:
                self._ended.discard((run, vehicle))  # a new run under the same name
            if (run, vehicle) not in self.runs and (not ev.alive or (run, vehicle) in self._ended):
                return  # a run is joined when a token of it appears (or its first frame)
            self._state(watcher, run, vehicle).liveliness(service, ev.alive, time.time())
            return
        key = (ev.run, ev.vehicle)
        if key in self._ended:
            return
        state = self._state(watcher, *key)
        state.heard_at = time.time()
        msg = self._see(state, ev)
        if msg is not None:  # a copy heard on a subscription: a gap in its seqs is a loss
            state.copies.see(f"{ev.service}/{ev.stream}", msg.seq)
        if (ev.service, ev.stream) == (CLOCK, END) and not self.opts.every_frame:
            # the run's last word: its tap still answers, so take the final state now (a run
            # faster than the poll rate would otherwise end between two polls)
            self._poll_run(watcher, key, state, full=True)

    def _see(self, state: RunState, f: WatchedFrame) -> Message | None:
        try:
            msg = decode(f.payload)
        except WireError as exc:
            state.rejected += 1
            if state.rejected == 1:
                log.warning("%s/%s: undecodable frame: %s", f.service, f.stream, exc)
            return None
        state.see(f.service, f.stream, msg, f.wall)
        return msg

    @property
    def _follow_events(self) -> bool:
        return not self.opts.every_frame and self.opts.rate_hz is None

    def _follow(
        self, watcher: Watcher, marks: PollMarks, keys: Keys, service: str, stream: str
    ) -> None:
        name = f"{service}/{stream}"
        if name not in marks.followed:
            marks.followed.add(name)
            watcher.follow(keys.watch(service, stream))

    def _polled(self, watcher: Watcher, state: RunState, marks: PollMarks, f: WatchedFrame) -> None:
        if not marks.take(f):
            return
        msg = self._see(state, f)
        if isinstance(msg, STATE_TYPES):
            marks.state_streams.add(f"{f.service}/{f.stream}")
        if isinstance(msg, EVENT_TYPES) and self._follow_events:
            self._follow(watcher, marks, Keys(f.run, f.vehicle), f.service, f.stream)

    def _poll(self, watcher: Watcher) -> None:
        """One poll of each run that is on (see _poll_run)."""
        now = time.time()
        for key, state in self.runs.items():
            if not state.over(now):
                self._poll_run(watcher, key, state)

    def _poll_others_due(self, watcher: Watcher) -> None:
        """The poll of every other stream, of each run on whose turn it is (every FULL_POLL_S):
        after the update showed the state, so that the state's reply never waits behind it."""
        now, mono = time.time(), time.monotonic()
        for key, state in self.runs.items():
            if not state.over(now) and mono >= self._polls[key].next_full:
                self._poll_others(watcher, key, state)

    def _poll_run(
        self, watcher: Watcher, key: tuple[str, str], state: RunState, *, full: bool = False
    ) -> None:
        """The frames the run's tap got since the last poll, newest only: of the vehicle's
        state streams, and of every other stream too when `full` (all of them while no state
        stream is known)."""
        marks = self._polls[key]
        if not marks.state_streams:
            n = self._poll_streams(watcher, key, state, marks.after_all)
            if n is not None:
                marks.after_state = marks.after_all = n
            marks.next_full = time.monotonic() + FULL_POLL_S
            return
        state_streams = sorted(marks.state_streams)
        n = self._poll_streams(watcher, key, state, marks.after_state, streams=state_streams)
        if n is not None:
            marks.after_state = max(marks.after_state, n)
        if full:
            self._poll_others(watcher, key, state)

    def _poll_others(self, watcher: Watcher, key: tuple[str, str], state: RunState) -> None:
        """The frames of every stream but the state's the tap got since the last such poll."""
        marks = self._polls[key]
        marks.next_full = time.monotonic() + FULL_POLL_S
        state_streams = sorted(marks.state_streams)
        n = self._poll_streams(watcher, key, state, marks.after_all, excluding=state_streams)
        if n is not None:
            marks.after_all = n

    def _poll_streams(
        self,
        watcher: Watcher,
        key: tuple[str, str],
        state: RunState,
        after: int,
        *,
        streams: list[str] | None = None,
        excluding: list[str] | None = None,
    ) -> int | None:
        """Take the newest frame of each stream (of `streams` only; never of `excluding`) the
        run's tap got after count `after`; the highest tap count among them, None if none."""
        frames = watcher.latest(
            Keys(*key), after=after, streams=streams or (), excluding=excluding or ()
        )
        for f in frames:
            self._polled(watcher, state, self._polls[key], f)
        return max((f.n for f in frames), default=None)

    def _drain(self, state: RunState) -> None:
        for ev in state.take_events():
            self.view.event(state, ev)

    def _forget_ended(self) -> None:
        """--follow: a run that ended leaves the dashboard once its end was shown."""
        now = time.time()
        for key in [k for k, s in self.runs.items() if s.over(now)]:
            del self.runs[key]
            self._polls.pop(key, None)
            self._ended.add(key)
