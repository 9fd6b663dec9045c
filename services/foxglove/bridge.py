"""The live Foxglove bridge's loop: finds a run on a router, and logs its view for the app.

It watches runs the way every watcher does (common/bus/watcher.py): a run is on while its
clock's liveliness token (service `runtime`) is; on joining one it asks the run's tap for
the scenario and the newest frame of every stream (late join), then translates each tapped
frame through the view (view.py) and logs it on a Foxglove WebSocket server. The server
outlives runs: when a run ends the app stays connected, and the next run (this name or any,
unless --run narrows it) is picked up; its start clears the app's state (a new session id).
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field

from foxglove import StatusLevel
from foxglove.websocket import WebSocketServer

from common.bus import CLOCK, Keys, Liveliness
from common.bus.gaps import SeqGaps
from common.bus.watcher import WatchedFrame, Watcher
from common.config.loader import ConfigError
from common.config.scenario import scenario_from_raw
from common.messages import WireError, decode
from services.foxglove.channels import ViewChannels
from services.foxglove.view import FoxgloveView

log = logging.getLogger("tidelink.foxglove")

POLL_S = 0.1  # longest wait for an event: how late a new subscriber gets its topic's replay
RETRY_S = 1.0  # between attempts to get a run's scenario from its tap
ROUTER_CHECK_S = 0.5  # between checks that the router is still there, while no run is on
STATUS_ID = "tidelink.run"


@dataclass
class Attached:
    """The run being served: its keys, its view, the tap count of each stream's last frame."""

    keys: Keys
    view: FoxgloveView
    last_n: dict[tuple[str, str], int] = field(default_factory=dict)
    frames: int = 0
    # copies that never came (gaps in each stream's seqs): the tap sends them DROP, and a
    # bridge that fell behind loses them
    gaps: SeqGaps = field(default_factory=SeqGaps)


class FoxgloveBridge:
    """One loop: watcher events in, view messages out on the server's channels."""

    def __init__(
        self,
        watcher: Watcher,
        server: WebSocketServer,
        channels: ViewChannels,
        where: str,
    ) -> None:
        self.watcher = watcher
        self.server = server
        self.channels = channels
        self.where = where  # the router's endpoint, for messages
        self.attached: Attached | None = None
        # the run that just ended: its clock token can overtake its last frames (the RunEnd,
        # the final statistics travel DROP at low priority), which are still shown
        self.ended: Attached | None = None
        self.alive: list[Keys] = []  # runs whose clock token is up, in the order they came
        self._next_try = 0.0
        self._undecodable = 0
        self._said_waiting = False

    def run_while(self, router_up: Callable[[], bool]) -> None:
        """Serve until interrupted (Shutdown, KeyboardInterrupt), or until `router_up` says
        the router is gone while no run is on: each `tidelink launch` brings its own router,
        and the caller opens a new session as soon as the next one listens (Zenoh's client
        reconnects by itself too, but after a back-off of seconds)."""
        next_check = time.monotonic() + ROUTER_CHECK_S
        while True:
            self.step(POLL_S)
            if self.attached is None and not self.alive and time.monotonic() >= next_check:
                if not router_up():
                    return
                next_check = time.monotonic() + ROUTER_CHECK_S

    def step(self, timeout_s: float) -> None:
        """Handle at most one watcher event, then any new subscriptions and pending attach."""
        ev = self.watcher.get(timeout_s)
        if isinstance(ev, Liveliness):
            self._on_liveliness(ev)
        elif isinstance(ev, WatchedFrame):
            self._on_frame(ev)
        self.channels.serve_subscriptions(0.0)
        if self.attached is None:
            self._try_attach()

    def _on_liveliness(self, ev: Liveliness) -> None:
        try:
            run, vehicle, service = Keys.parse_alive(ev.key)
        except ValueError:
            return
        if service != CLOCK:
            return  # services come and go (restarts); the run is the clock's
        keys = Keys(run, vehicle)
        if ev.alive:
            if keys not in self.alive:
                self.alive.append(keys)
                log.info("run %s/%s is on", run, vehicle)
            return
        if keys in self.alive:
            self.alive.remove(keys)
        if self.attached is not None and self.attached.keys == keys:
            log.info(
                "run %s/%s is over (%d frames shown, %d lost); waiting for the next run on %s",
                run,
                vehicle,
                self.attached.frames,
                self.attached.gaps.total,
                self.where,
            )
            self.server.publish_status(
                f"run {run}/{vehicle} is over; waiting for the next run",
                StatusLevel.Info,
                STATUS_ID,
            )
            self.ended, self.attached = self.attached, None
            self._said_waiting = True
            self._next_try = 0.0

    def _try_attach(self) -> None:
        if not self.alive:
            if not self._said_waiting:
                log.info("no run on %s yet; waiting for one", self.where)
                self.server.publish_status(
                    f"no run on {self.where} yet; waiting", StatusLevel.Info, STATUS_ID
                )
                self._said_waiting = True
            return
        now = time.monotonic()
        if now < self._next_try:
            return
        self._next_try = now + RETRY_S
        keys = self.alive[0]
        raw = self.watcher.scenario(keys, timeout_s=2.0)
        if raw is None:
            log.warning(
                "run %s/%s: its tap did not answer with the scenario; retrying", *_ids(keys)
            )
            return
        try:
            view = FoxgloveView(scenario_from_raw(raw, f"scenario of {keys.root}"))
        except ConfigError as exc:
            log.error("run %s/%s: cannot read its scenario: %s", *_ids(keys), exc)
            self.alive.remove(keys)
            return
        self._attach(keys, view)

    def _attach(self, keys: Keys, view: FoxgloveView) -> None:
        # a new session id makes the app drop the previous run's messages (trails, plots)
        self.server.clear_session(f"{keys.run}/{keys.vehicle}/{time.time():.3f}")
        self.channels.forget()
        self.attached, self.ended = Attached(keys, view), None
        self._said_waiting = False
        now_ns = time.time_ns()
        for vm in view.static():
            self.channels.log(vm, now_ns)
        latest = self.watcher.latest(keys, timeout_s=2.0)
        for f in latest:
            self._on_frame(f)
        log.info(
            "watching run %s/%s (joined with the newest frame of %d streams)",
            keys.run,
            keys.vehicle,
            len(latest),
        )
        self.server.remove_status([STATUS_ID])

    def _on_frame(self, f: WatchedFrame) -> None:
        a = self.attached or self.ended
        if a is None or (f.run, f.vehicle) != (a.keys.run, a.keys.vehicle):
            return
        stream = (f.service, f.stream)
        if f.n <= a.last_n.get(stream, 0):
            return  # already shown: a late-join frame the subscription also delivered
        a.last_n[stream] = f.n
        try:
            msg = decode(f.payload)
        except WireError as exc:
            self._undecodable += 1
            if self._undecodable == 1:
                log.warning("ignoring an undecodable frame on %s/%s: %s", *stream, exc)
            return
        a.frames += 1
        a.gaps.see(f"{f.service}/{f.stream}", msg.seq)
        log_time_ns = int(f.wall * 1e9)  # when the run's tap got it: one clock for all topics
        for vm in a.view.translate(f.service, f.stream, msg):
            self.channels.log(vm, log_time_ns)


def _ids(keys: Keys) -> tuple[str, str]:
    return keys.run, keys.vehicle
