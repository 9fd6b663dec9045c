"""A watcher's end of the bus: which runs are on a router, their tapped frames, their latest
state and scenario (the run's side is common/bus/tap.py).

Monitors, Foxglove bridges and remote recorders all watch a run this way, and never
subscribe to the control streams themselves (see tap.py for why).
"""

from __future__ import annotations

import json
import logging
import queue
from collections.abc import Iterable
from typing import NamedTuple

from common.bus.bus import Bus, Liveliness, RawFrame
from common.bus.keys import CLOCK, PROBE, WATCH, Keys
from common.jsonsafe import JsonObject
from common.messages import WireError, decode_watch

log = logging.getLogger("tidelink.watch")

# After a run's clock token vanished, how long a watcher still waits for its RunEnd: the
# RunEnd travels at DATA_LOW behind the tap's copies and can arrive after the token's end
# (seen under load)
END_GRACE_S = 3.0


class WatchedFrame(NamedTuple):
    """A frame of a watched run: which stream, the bytes that crossed the wire, and when the
    run's tap got it (wall: Unix seconds; n: the tap's running count)."""

    run: str
    vehicle: str
    service: str
    stream: str
    payload: bytes
    attachment: bytes | None
    wall: float
    n: int


def watched(f: RawFrame) -> WatchedFrame:
    """A tapped frame (from Keys.watch or Keys.latest) with its key and stamp parsed;
    ValueError (WireError) when the key or the tap's attachment is not one."""
    run, vehicle, service, stream = Keys.parse_watch(f.key)
    if f.attachment is None:
        raise WireError(f"{f.key}: a watch frame without the tap's attachment")
    wall, n, att = decode_watch(f.attachment)
    return WatchedFrame(run, vehicle, service, stream, f.payload, att, wall, n)


WatchEvent = WatchedFrame | Liveliness


class Watcher:
    """Watches the runs on a router (one run and vehicle, or every one when None).

    Tapped frames and liveliness changes arrive on Zenoh's threads and queue up for `get`,
    so a watcher's loop is single-threaded. The queue is unbounded in frames but a slow
    watcher never slows the run: the tap publishes DROP, so the router drops for it.
    """

    def __init__(self, bus: Bus, run: str | None = None, vehicle: str | None = None) -> None:
        self.bus = bus
        self.run = run
        self.vehicle = vehicle
        self._q: queue.SimpleQueue[WatchEvent] = queue.SimpleQueue()
        self.rejected = 0  # frames that were not tapped frames (counted, logged once)

    def start(self, *, frames: bool = True) -> None:
        """Hear liveliness (tokens already there included) and, if `frames`, every tapped
        frame (a thin-linked watcher polls `latest` instead)."""
        self.bus.on_alive(Keys.matching(self.run, self.vehicle).all_alive, self._q.put)
        if frames:
            self.bus.subscribe_raw(Keys.matching(self.run, self.vehicle).all_watch, self._on_frame)

    def follow(self, key_expr: str) -> None:
        """Also hear every tapped frame on `key_expr` (some streams of a run, e.g. the ones
        that carry events, when the rest is polled)."""
        self.bus.subscribe_raw(key_expr, self._on_frame)

    def _on_frame(self, f: RawFrame) -> None:
        if f.key.endswith(f"/{WATCH}/{CLOCK}/{PROBE}"):
            return  # a replay checking that its puts get through (common/bus/probe.py)
        try:
            self._q.put(watched(f))
        except (ValueError, WireError) as exc:
            self.rejected += 1
            if self.rejected == 1:
                log.warning("ignoring a frame that is not a tapped frame: %s", exc)

    def get(self, timeout: float | None) -> WatchEvent | None:
        """The next event, or None after `timeout` seconds without one."""
        try:
            return self._q.get(timeout=timeout)
        except queue.Empty:
            return None

    def latest(
        self,
        keys: Keys,
        *,
        after: int = 0,
        streams: Iterable[str] = (),
        excluding: Iterable[str] = (),
        timeout_s: float = 1.0,
    ) -> list[WatchedFrame]:
        """The newest frame of every stream of a run whose tap count is above `after` (of the
        `streams` named "<service>/<stream>" only, when any are; never of those `excluding`)."""
        out = []
        selector = f"{keys.all_latest}?after={after}"
        if names := "|".join(streams):
            selector += f";streams={names}"
        if skipped := "|".join(excluding):
            selector += f";except={skipped}"
        for f in self.bus.query(selector, timeout_s=timeout_s):
            try:
                out.append(watched(f))
            except (ValueError, WireError) as exc:
                log.warning("ignoring a reply that is not a tapped frame: %s", exc)
        return sorted(out, key=lambda w: w.n)

    def scenario(self, keys: Keys, *, timeout_s: float = 1.0) -> JsonObject | None:
        """The run's scenario (the raw dict it was launched with), or None if none answered."""
        return self._json(keys.scenario, timeout_s)

    def alive(self, keys: Keys, *, timeout_s: float = 1.0) -> list[str]:
        """The services of the run whose liveliness tokens are present now."""
        out = []
        for key in self.bus.alive_now(keys.all_alive, timeout_s=timeout_s):
            try:
                out.append(Keys.parse_alive(key)[2])
            except ValueError:
                continue
        return out

    def dataflow(self, keys: Keys, *, timeout_s: float = 1.0) -> JsonObject | None:
        """The run's declared dataflow as it answered (Dataflow.describe(), unchecked: read it
        with dataflow.read_description), or None if none answered."""
        return self._json(keys.dataflow, timeout_s)

    def _json(self, key: str, timeout_s: float) -> JsonObject | None:
        for f in self.bus.query(key, timeout_s=timeout_s):
            try:
                data = json.loads(f.payload)
            except ValueError:
                continue
            if isinstance(data, dict):
                return data
        return None
