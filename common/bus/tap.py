"""The run's window for watchers: every stream copied to Keys.watch, the newest frame of each
served on Keys.latest, the scenario served on Keys.scenario.

The tap lives in the clock's process, which subscribes to every stream of the run anyway (it
keeps the run's record). Watchers (monitors, Foxglove bridges, remote recorders) never
subscribe to the control streams themselves: those are published BLOCK, and a router waits
for a subscriber that stopped reading before it forwards the next BLOCK sample to anyone
(docs/notes/0002-watch-tap-drop-copies.md). The tap's copies are published DROP at priority
DATA_LOW, so a stalled or thin-linked watcher loses copies of its own and nothing else. The
RunEnd alone is published BLOCK: the run is over by then, and a watcher slow at the end still
learns how it ended.

Late join: state that is not re-sent often (the path in force, the obstacle tracks, the
vehicle's mode, the scenario's static world) is answered by queryables, Zenoh's own way of
asking "what is it now": a watcher that joins queries Keys.all_latest and Keys.scenario once.
A thin-linked watcher polls Keys.all_latest with `?after=N` at its own rate instead of
subscribing: the tap answers only with frames newer than its count N, so the decimation is
done here, before the thin link. `;streams=<service>/<stream>|...` narrows a reply to those
streams and `;except=...` leaves those out (a monitor polls the vehicle's state often and the
rest, about three quarters of a full reply's bytes on the default mission, seldom and apart).
"""

from __future__ import annotations

import json
import logging
import threading
import time
from collections.abc import Callable

import zenoh

from common.bus.bus import Bus, Publisher, RawFrame
from common.bus.keys import CLOCK, END, Keys
from common.bus.watcher import WatchedFrame
from common.jsonsafe import JsonObject
from common.messages import RunEnd, encode, encode_watch

log = logging.getLogger("tidelink.tap")

SCENARIO_ENCODING = "application/json"


class WatchTap:
    """Copies a run's streams for watchers and answers their late-join queries."""

    def __init__(
        self, bus: Bus, keys: Keys, scenario_raw: JsonObject, *, listen: bool = True
    ) -> None:
        """`listen`: copy every stream the run's bus carries; else only what is `feed`-ed (a
        replay, which puts nothing on the run's control keys)."""
        self.bus = bus
        self.keys = keys
        self._lock = threading.Lock()
        self._taken = threading.Condition(self._lock)  # notified per frame (see caught_up)
        # threads in caught_up: a frame notifies only when there is one (the lockstep
        # coordinator feeds every frame on its tick's path, and a notify is Python code)
        self._waiting = 0
        self._n = 0
        self._latest: dict[str, RawFrame] = {}  # latest key -> frame as a query reply
        self._latest_n: dict[str, int] = {}
        self._latest_name: dict[str, str] = {}  # latest key -> "<service>/<stream>"
        # per stream: its latest key, name and copies' publisher (_outlet)
        self._outlets: dict[tuple[str, str], tuple[str, str, Publisher]] = {}
        self._sinks: list[Callable[[WatchedFrame], None]] = []
        self._closed = False
        scenario = json.dumps(scenario_raw, sort_keys=True).encode()
        bus.serve(keys.scenario, lambda: scenario, encoding=SCENARIO_ENCODING)
        bus.serve_frames(keys.all_latest, self._answer)
        if listen:
            bus.subscribe_raw(keys.all_streams, self._take)

    def add_sink(self, sink: Callable[[WatchedFrame], None]) -> None:
        """Also hand every tapped frame to `sink`, on Zenoh's thread (an in-process recorder:
        it must only enqueue)."""
        with self._lock:
            self._sinks.append(sink)

    @property
    def count(self) -> int:
        """Frames tapped so far."""
        return self._n

    def caught_up(self, count: int, *, timeout_s: float) -> bool:
        """Wait until `count` frames have been tapped (False after `timeout_s` without).

        The tap's subscription and the driver's are served by different Zenoh callbacks:
        when the driver has recorded its last frame, the tap may not have seen it yet. Ending
        the tap then would leave that frame out of every watcher's and recorder's view.
        """
        with self._taken:
            self._waiting += 1
            try:
                return self._taken.wait_for(lambda: self._n >= count, timeout_s)
            finally:
                self._waiting -= 1

    def _take(self, f: RawFrame) -> None:
        service, stream = self.keys.split(f.key)
        if service == CLOCK:
            return  # the clock's own protocol (acks), not a stream of the mission
        self.feed(service, stream, f.payload, f.attachment)

    def feed(self, service: str, stream: str, payload: bytes, attachment: bytes | None) -> None:
        """Copy one frame of `service`/`stream` for watchers (what the run's bus carried, or
        what a replay reads from its recording)."""
        with self._lock:
            if self._closed:
                return
            out = self._outlets.get((service, stream))
            if out is None:
                out = self._outlets[(service, stream)] = self._outlet(service, stream)
            latest, name, pub = out
            self._n += 1
            if self._waiting:
                self._taken.notify_all()
            n, wall = self._n, time.time()
            att = encode_watch(wall, n, attachment)
            self._latest[latest] = RawFrame(latest, payload, att)
            self._latest_n[latest] = n
            self._latest_name[latest] = name
            sinks = list(self._sinks) if self._sinks else ()
        pub.put_bytes(payload, att)
        if sinks:
            tapped = WatchedFrame(
                self.keys.run, self.keys.vehicle, service, stream, payload, attachment, wall, n
            )
            for sink in sinks:
                sink(tapped)

    def _outlet(self, service: str, stream: str) -> tuple[str, str, Publisher]:
        """A stream's latest key, its name and its copies' publisher (made once per stream:
        a lockstep coordinator feeds the tap every frame on its tick's path)."""
        name = f"{service}/{stream}"
        pub = self.bus.monitoring_publisher(self.keys.watch(service, stream))
        return self.keys.latest(service, stream), name, pub

    def _answer(self, key_expr: str, params: dict[str, str]) -> list[RawFrame]:
        """The newest frame of every stream matching the query, newer than `?after=N`, of the
        streams named by `;streams=a/b|c/d` only when given, but those named by `;except=`."""
        try:
            after = int(params.get("after", "0"))
        except ValueError:
            after = 0
        only = set(params["streams"].split("|")) if params.get("streams") else None
        skip = set(params["except"].split("|")) if params.get("except") else set()
        asked = zenoh.KeyExpr(key_expr)
        with self._lock:
            return [
                f
                for k, f in self._latest.items()
                if self._latest_n[k] > after
                and (only is None or self._latest_name.get(k) in only)
                and self._latest_name.get(k) not in skip
                and asked.intersects(zenoh.KeyExpr(k))
            ]

    def end(self, reason: str, t_end: float, ticks: int) -> None:
        """Announce the run's end on Keys.end (a RunEnd message); stop tapping."""
        data = encode(RunEnd(stamp=t_end, reason=reason, ticks=ticks, source=CLOCK, seq=1))
        with self._lock:
            self._closed = True
            self._n += 1
            n, wall = self._n, time.time()
            att = encode_watch(wall, n, None)
            sinks = list(self._sinks)
            latest = self.keys.latest(CLOCK, END)
            self._latest[latest] = RawFrame(latest, data, att)
            self._latest_n[latest] = n
            self._latest_name[latest] = f"{CLOCK}/{END}"
        for sink in sinks:
            sink(WatchedFrame(self.keys.run, self.keys.vehicle, CLOCK, END, data, None, wall, n))
        try:
            self.bus.monitoring_publisher(self.keys.end, last=True).put_bytes(data, att)
        except Exception as exc:  # noqa: BLE001 - a closing bus must not hide the run's result
            log.warning("could not announce the run's end: %s", exc)
