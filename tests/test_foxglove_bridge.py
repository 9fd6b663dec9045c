"""`tidelink foxglove`: the bridge's loop against fakes, and end to end with real runs, a real
router and a Foxglove WebSocket client written from the protocol (helpers/foxglove_client.py).

The end-to-end tests synchronise on the lines the bridge and the launcher print and on what
the client receives, always with deadlines (helpers/launch_proc.py).
"""

from __future__ import annotations

import json
import logging
import signal
import socket
from collections import deque
from pathlib import Path
from typing import Any

import foxglove
import pytest
from helpers.foxglove_client import (
    LEGACY_SUBPROTOCOL,
    SUBPROTOCOL,
    FoxgloveClient,
    schema_bytes,
)
from helpers.launch_proc import REPO, Tidelink, kill_recorded
from helpers.protobuf_wire import Schemas
from websockets.exceptions import InvalidStatus
from websockets.sync.client import connect
from websockets.typing import Subprotocol

from common.bus import Liveliness
from common.bus.watcher import WatchedFrame
from common.config.scenario import load_scenario
from common.messages import Message, TruthState, encode
from common.runtime.processes.children import free_port
from common.view import ViewMessage
from services.foxglove.bridge import FoxgloveBridge
from services.foxglove.channels import SDK_CLIENT_LOGGER, ViewChannels
from services.foxglove.serve import BridgeOptions, start_server

WAIT_S = 60.0  # upper bound on any one wait; the happy paths take seconds
DEFAULT = REPO / "configs" / "default.toml"
SHORT = REPO / "configs" / "experiments" / "scenarios" / "short.toml"
PROTOBUF_TOPICS = {
    "/vehicle/pose_true": "foxglove.PoseInFrame",
    "/vehicle/pose_est": "foxglove.PoseInFrame",
    "/planner/path": "foxglove.SceneUpdate",
    "/scene/static": "foxglove.SceneUpdate",
    "/scene/tracks": "foxglove.SceneUpdate",
}


# -- the loop, against fakes -----------------------------------------------------------------
class FakeWatcher:
    """Scripted watcher events; scenarios and latest frames per run name."""

    def __init__(self) -> None:
        self.events: deque[Any] = deque()
        self.scenarios: dict[str, dict[str, Any]] = {}
        self.latest_frames: dict[str, list[WatchedFrame]] = {}

    def get(self, timeout: float | None) -> Any:
        return self.events.popleft() if self.events else None

    def scenario(self, keys: Any, *, timeout_s: float = 1.0) -> dict[str, Any] | None:
        return self.scenarios.get(keys.run)

    def latest(self, keys: Any, *, after: int = 0, timeout_s: float = 1.0) -> list[WatchedFrame]:
        return self.latest_frames.get(keys.run, [])


class FakeServer:
    def __init__(self) -> None:
        self.sessions: list[str] = []
        self.statuses: list[str] = []

    def clear_session(self, session_id: str | None = None) -> None:
        self.sessions.append(str(session_id))

    def publish_status(self, message: str, level: Any, id: str | None = None) -> None:
        self.statuses.append(message)

    def remove_status(self, ids: list[str]) -> None:
        pass


class FakeChannels(ViewChannels):
    """ViewChannels with no server: what is logged and replayed is noted instead."""

    def __init__(self) -> None:
        super().__init__(foxglove.Context())
        self.logged: list[ViewMessage] = []
        self.replayed: list[str] = []

    def log(self, vm: ViewMessage, log_time_ns: int) -> None:
        self.logged.append(vm)

    def replay(self, topic: str) -> None:
        self.replayed.append(topic)

    def forget(self) -> None:
        pass

    def topics(self) -> list[str]:
        return [vm.topic for vm in self.logged]


def _frame(run: str, n: int, msg: Message | None, service: str = "vehicle") -> WatchedFrame:
    payload = b"\x93not a frame" if msg is None else encode(msg)
    return WatchedFrame(run, "auv1", service, "truth", payload, None, 1.0e9 + n, n)


def _clock(run: str, alive: bool) -> Liveliness:
    return Liveliness(f"tidelink/{run}/auv1/alive/runtime", alive)


def test_the_loop_joins_late_shows_each_frame_once_and_moves_to_the_next_run() -> None:
    _, raw = load_scenario(DEFAULT)
    watcher, server, channels = FakeWatcher(), FakeServer(), FakeChannels()
    watcher.scenarios = {"r1": raw, "r2": {**raw, "run": {**raw["run"], "name": "r2"}}}
    truth = [
        TruthState(stamp=0.1 * n, x=5.0 + n, y=20.0, theta=0.0, v=1.0, w=0.0) for n in range(9)
    ]
    watcher.latest_frames = {"r1": [_frame("r1", 3, truth[3])]}
    bridge = FoxgloveBridge(watcher, server, channels, "tcp/x:1")  # type: ignore[arg-type]
    bridge.step(0.0)
    assert channels.logged == [] and "no run on tcp/x:1 yet; waiting" in server.statuses
    watcher.events.append(_clock("r1", True))
    bridge.step(0.0)
    assert len(server.sessions) == 1 and server.sessions[0].startswith("r1/auv1/")
    topics = channels.topics()
    assert topics[:2] == ["/scene/static", "/run/info"] and "/vehicle/pose_true" in topics
    n_joined = len(channels.logged)
    watcher.events.extend(
        [
            _frame("r1", 3, truth[3]),  # the late-join frame again, from the subscription
            _frame("r9", 4, truth[4]),  # another run
            _frame("r1", 5, None),  # undecodable
            Liveliness("tidelink/r1/auv1/alive/planner", False),  # a service, not the run
            _frame("r1", 6, truth[6]),
        ]
    )
    for _ in range(5):
        bridge.step(0.0)
    poses = [vm for vm in channels.logged[n_joined:] if vm.topic == "/vehicle/pose_true"]
    assert len(poses) == 1  # only frame 6 is new
    assert bridge.attached is not None and bridge.attached.frames == 2  # frames 3 and 6
    channels.listener.subscribed.put("/scene/static")
    bridge.step(0.0)
    assert channels.replayed == ["/scene/static"]
    # r1's token goes before its last frame (it can overtake it): that frame is still shown
    watcher.events.extend([_clock("r1", False), _frame("r1", 7, truth[7])])
    bridge.step(0.0)
    bridge.step(0.0)
    assert bridge.attached is None and "run r1/auv1 is over; waiting for the next run" in (
        server.statuses
    )
    assert [vm.topic for vm in channels.logged].count("/vehicle/pose_true") == 3  # 3, 6, 7
    # the next run to come is shown (its own session and scenario); r1's frames no longer
    watcher.events.extend([_clock("r2", True), _frame("r1", 8, truth[8])])
    bridge.step(0.0)
    bridge.step(0.0)
    assert len(server.sessions) == 2 and server.sessions[1].startswith("r2/auv1/")
    assert [vm.topic for vm in channels.logged].count("/vehicle/pose_true") == 3
    info = [json.loads(vm.data) for vm in channels.logged if vm.topic == "/run/info"]
    assert [i["name"] for i in info] == ["demo", "r2"]  # r1's raw scenario names it "demo"


def test_a_port_in_use_is_a_clear_error() -> None:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with Tidelink("foxglove", "--port", str(port), "--connect", "tcp/127.0.0.1:9") as t:
            assert t.wait(WAIT_S) == 1
    assert f"cannot serve on 127.0.0.1:{port}" in t.stderr and "--port" in t.stderr, t.stderr


def _pose(data: bytes) -> ViewMessage:
    """A view message on the true pose's topic carrying `data` (JSON)."""
    return ViewMessage(
        topic="/vehicle/pose_true",
        schema_name="Pose",
        schema_encoding="jsonschema",
        schema=b'{"type": "object"}',
        message_encoding="json",
        data=data,
    )


def test_a_subscription_refused_as_to_an_unknown_channel_is_mended_by_advertising_it_again() -> (
    None
):
    # the SDK's server may refuse a subscription that overtakes its own bookkeeping of an
    # advertisement (services/foxglove/channels.py); the bridge hears it through the SDK's
    # log and advertises the channel again, with its newest message
    channels = ViewChannels(foxglove.Context())
    server = start_server(BridgeOptions(port=free_port()), channels)
    try:
        with FoxgloveClient(f"ws://127.0.0.1:{server.port}") as client:
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            vm = _pose(b'{"x": 1}')
            channels.log(vm, 1)  # advertised; the client subscribes, then gets it replayed

            def served(n: int) -> bool:
                channels.serve_subscriptions(0.0)  # the bridge's loop
                return len(client.on(vm.topic)) >= n

            client.wait_until(lambda: served(1), WAIT_S, "the first pose")
            first = client.channel(vm.topic)["id"]
            # the SDK's own words for a refusal, on its logger: a subscription to an id it
            # never advertised (nothing of ours has it: nothing to mend)
            client.ws.send(
                json.dumps({"op": "subscribe", "subscriptions": [{"id": 99, "channelId": 999}]})
            )
            client.wait_until(lambda: not channels.lost.channel_ids.empty(), WAIT_S, "the refusal")
            channels.serve_subscriptions(0.0)
            assert channels.readvertised == 0
            # the race itself cannot be forced: what the SDK logs when the client loses it
            logging.getLogger(SDK_CLIENT_LOGGER).error(
                "Client 127.0.0.1:1 attempted to subscribe to unknown channel: %d", first
            )

            client.wait_until(lambda: served(2), WAIT_S, "the pose again, advertised again")
            assert client.channel(vm.topic)["id"] != first
            assert channels.readvertised == 1
            assert first not in client.channels  # unadvertised
    finally:
        server.stop()
        channels.close()
    assert channels.lost not in logging.getLogger(SDK_CLIENT_LOGGER).handlers


def test_a_topics_first_message_reaches_a_client_once_when_its_subscription_comes_first(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # the race behind a run announced twice: the client subscribes to a new channel between
    # its advertisement and the first message's log (the bridge's thread descheduled there);
    # the first message must reach it once, through the replay, not also logged live
    channels = ViewChannels(foxglove.Context())
    server = start_server(BridgeOptions(port=free_port()), channels)
    try:
        with FoxgloveClient(f"ws://127.0.0.1:{server.port}") as client:
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            make_channel = foxglove.Channel

            def advertised_then_subscribed(*args: Any, **kwargs: Any) -> foxglove.Channel:
                channel = make_channel(*args, **kwargs)
                client.wait_until(
                    lambda: not channels.listener.subscribed.empty(), WAIT_S, "the subscription"
                )
                return channel

            monkeypatch.setattr(foxglove, "Channel", advertised_then_subscribed)
            channels.log(_pose(b'{"x": 1}'), 1)
            monkeypatch.undo()
            channels.serve_subscriptions(0.0)  # the bridge's loop: the replay
            channels.log(_pose(b'{"x": 2}'), 2)  # after anything sent before it, in order

            client.wait_until(
                lambda: any(m.data == b'{"x": 2}' for m in client.on("/vehicle/pose_true")),
                WAIT_S,
                "the second pose",
            )
            assert [m.data for m in client.on("/vehicle/pose_true")] == [
                b'{"x": 1}',
                b'{"x": 2}',
            ]
    finally:
        server.stop()
        channels.close()


# -- the subprotocol: foxglove.websocket.v1 as well as foxglove.sdk.v1 -------------------------
@pytest.mark.parametrize("subprotocol", [LEGACY_SUBPROTOCOL, SUBPROTOCOL])
def test_a_client_of_either_subprotocol_name_is_served_the_channels(subprotocol: str) -> None:
    # the SDK's server takes only foxglove.sdk.v1*; the bridge's proxy takes ws-protocol's
    # foxglove.websocket.v1 too, and answers with the name the client offered
    channels = ViewChannels(foxglove.Context())
    server = start_server(BridgeOptions(port=free_port()), channels)
    try:
        with FoxgloveClient(f"ws://127.0.0.1:{server.port}", subprotocol=subprotocol) as client:
            assert client.subprotocol == subprotocol
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            vm = _pose(b'{"x": 1}')
            channels.log(vm, 1)

            def served() -> bool:
                channels.serve_subscriptions(0.0)  # the bridge's loop
                return bool(client.on(vm.topic))

            client.wait_until(served, WAIT_S, "the pose")
            assert client.channel(vm.topic)["schemaName"] == "Pose"
            assert client.on(vm.topic)[0].data == b'{"x": 1}'
    finally:
        server.stop()
        channels.close()


def test_a_client_offering_neither_name_gets_a_400_that_names_both() -> None:
    channels = ViewChannels(foxglove.Context())
    server = start_server(BridgeOptions(port=free_port()), channels)
    try:
        with pytest.raises(InvalidStatus) as info:
            connect(f"ws://127.0.0.1:{server.port}", subprotocols=[Subprotocol("foxglove.v9")])
        response = info.value.response
        assert response.status_code == 400
        body = response.body.decode()
        assert "speaks the subprotocols foxglove.websocket.v1, foxglove.sdk.v1 and" in body
        assert "(it offered foxglove.v9)" in body
        # a plain HTTP request (a browser on the URL) is told the same
        with socket.create_connection(("127.0.0.1", server.port), timeout=WAIT_S) as s:
            s.sendall(b"GET / HTTP/1.1\r\nHost: x\r\n\r\n")
            reply = b""
            while chunk := s.recv(4096):
                reply += chunk
        assert reply.startswith(b"HTTP/1.1 400 ") and b"foxglove.websocket.v1" in reply
        assert b"it offered none" in reply
    finally:
        server.stop()
        channels.close()


def test_closing_the_server_ends_its_clients_connections() -> None:
    channels = ViewChannels(foxglove.Context())
    server = start_server(BridgeOptions(port=free_port()), channels)
    stopped = False
    try:
        with FoxgloveClient(
            f"ws://127.0.0.1:{server.port}", subprotocol=LEGACY_SUBPROTOCOL
        ) as client:
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            server.stop()  # joins the proxy's threads: returns only once they ended
            stopped = True
            client.wait_until(lambda: client.closed, WAIT_S, "the connection's end")
    finally:
        if not stopped:
            server.stop()
        channels.close()


# -- end to end ------------------------------------------------------------------------------
def _decode(client: FoxgloveClient, topic: str, index: int = -1) -> dict[str, Any]:
    """A received message decoded with the schema its channel advertised."""
    ch = client.channel(topic)
    return Schemas(schema_bytes(ch)).decode(f".{ch['schemaName']}", client.on(topic)[index].data)


def _entities(update: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {e["id"]: e for e in update["entities"]}


@pytest.fixture
def out(tmp_path: Path) -> Any:
    d = tmp_path / "run"
    yield d
    kill_recorded(d / "pids.json")


def _run(name: str, router: str, out: Path, max_time_s: float) -> Tidelink:
    """A realtime run of the short mission at 8x whose own process is the router on `router`."""
    return Tidelink(
        "run", str(SHORT), "--runtime", "realtime", "--time-scale", "8",
        "--out", str(out / name), "--set", f"run.name={name}",
        "--set", f"run.max_time_s={max_time_s}", "--set", f'bus.listen=["{router}"]',
    )  # fmt: skip


def _run_segments(client: FoxgloveClient) -> list[list[float]]:
    """The true pose stamps (mission s) of each run, split where a run's /run/info came."""
    ch = client.channel("/vehicle/pose_true")
    schemas = Schemas(schema_bytes(ch))
    runs: list[list[float]] = []
    for m in client.messages:
        if m.topic == "/run/info":
            runs.append([])
        elif m.topic == "/vehicle/pose_true" and runs:
            ts = schemas.decode(".foxglove.PoseInFrame", m.data)["timestamp"]
            runs[-1].append(ts["seconds"] + 1e-9 * ts["nanos"])
    return runs


def _pump_until_logged(client: FoxgloveClient, bridge: Tidelink, line: str, start: int) -> None:
    """Keep reading the socket, as the app does, until the bridge logs `line` (a server's
    queue for a client that does not read is bounded: it may drop what was sent meanwhile)."""

    def logged() -> bool:
        return any(line in x for x in bridge.err[start:])

    client.wait_until(logged, WAIT_S, f"the bridge's {line!r}")


def _arrivals(client: FoxgloveClient) -> list[tuple[str, int]]:
    """The client's run infos and true poses as (topic, count) runs in arrival order: what
    a failure shows."""
    out: list[tuple[str, int]] = []
    for m in client.messages:
        if m.topic not in ("/run/info", "/vehicle/pose_true"):
            continue
        if out and out[-1][0] == m.topic:
            out[-1] = (m.topic, out[-1][1] + 1)
        else:
            out.append((m.topic, 1))
    return out


@pytest.mark.slow
def test_the_bridge_waits_for_a_router_and_a_run_then_follows_runs_one_after_another(
    tmp_path: Path,
) -> None:
    rp, wp = free_port(), free_port()
    router = f"tcp/127.0.0.1:{rp}"
    with Tidelink("foxglove", "--connect", router, "--port", str(wp)) as bridge:
        bridge.wait_for(f"no router at {router} yet; waiting", WAIT_S)
        with FoxgloveClient(f"ws://127.0.0.1:{wp}") as client:
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            # each run is its own router: the second comes after the first one's has gone
            for n, name in enumerate(("first", "second"), start=1):
                start = len(bridge.err)
                with _run(name, router, tmp_path, 20.0) as run:
                    _pump_until_logged(client, bridge, f"watching run {name}/auv1", start)
                    while run.proc.poll() is None:
                        client.pump(0.2)
                    assert run.wait(WAIT_S) == 3, run.stderr  # max_time: goal not reached
                _pump_until_logged(client, bridge, f"run {name}/auv1 is over", start)

                def infos(n: int = n) -> bool:
                    return len(client.on("/run/info")) >= n

                client.wait_until(infos, WAIT_S, f"{name}'s /run/info")
            client.pump(0.5)
            assert not client.closed
        names = [json.loads(m.data)["name"] for m in client.on("/run/info")]
        if names != ["first", "second"]:
            # each attach announces its run once (fresh clone 92 once saw first, first,
            # second: the race of the test above can do that); in full, with the bridge's log
            pytest.fail(
                f"runs announced {names}; arrivals {_arrivals(client)}; sessions "
                f"{[s['sessionId'] for s in client.server_infos]}\nbridge log:\n"
                f"{bridge.stderr[-6000:]}"
            )
        sessions = [s["sessionId"] for s in client.server_infos]
        assert [x.split("/")[0] for x in sessions[1:]] == ["first", "second"]
        # both runs were shown from (about) their start, the second too: the bridge opened a
        # new session as soon as its router listened, without waiting out Zenoh's back-off
        # (~6 s of wall clock, ~48 mission s at 8x; 10 s leaves a loaded machine 1.25 s)
        for name, stamps in zip(names, _run_segments(client), strict=True):
            if not (stamps and min(stamps) < 10.0 and max(stamps) > 15.0):
                # in full (an assertion's message is cut short): what the client was told and
                # sent, the frames it could not route, and the bridge's log
                pytest.fail(
                    f"run {name}: true pose stamps {stamps[:3]}...; arrivals "
                    f"{_arrivals(client)}; unrouted frames by subscription id "
                    f"{client.unrouted}\nclient operations:\n  "
                    + "\n  ".join(client.ops)
                    + f"\nbridge log:\n{bridge.stderr[-6000:]}"
                )
        bridge.signal(signal.SIGTERM)
        assert bridge.wait(WAIT_S) == 0, bridge.stderr
        assert "the router at" in bridge.stderr and "is gone" in bridge.stderr


@pytest.mark.slow
def test_a_foxglove_websocket_v1_client_receives_a_runs_channels(tmp_path: Path) -> None:
    # the client of the protocol's long-standing name, as ws-protocol's libraries and older
    # apps connect, against the bridge process and a real run
    rp, wp = free_port(), free_port()
    router = f"tcp/127.0.0.1:{rp}"
    with Tidelink("foxglove", "--connect", router, "--port", str(wp)) as bridge:
        bridge.wait_for(f"no router at {router} yet; waiting", WAIT_S)
        assert f"(subprotocol {LEGACY_SUBPROTOCOL} or {SUBPROTOCOL})" in bridge.stderr
        url = f"ws://127.0.0.1:{wp}"
        with FoxgloveClient(url, subprotocol=LEGACY_SUBPROTOCOL) as client:
            assert client.subprotocol == LEGACY_SUBPROTOCOL
            client.wait_until(lambda: bool(client.server_infos), WAIT_S, "serverInfo")
            with _run("legacy", router, tmp_path, 20.0) as run:
                _pump_until_logged(client, bridge, "watching run legacy/auv1", 0)
                client.wait_until(
                    lambda: (
                        PROTOBUF_TOPICS.keys() <= client.advertised_topics
                        and {"/run/info", "/vehicle/pose_true"}
                        <= {m.topic for m in client.messages}
                    ),
                    WAIT_S,
                    "the run's channels and its first poses",
                )
                while run.proc.poll() is None:
                    client.pump(0.2)
                assert run.wait(WAIT_S) == 3, run.stderr  # max_time: goal not reached
            assert [json.loads(m.data)["name"] for m in client.on("/run/info")] == ["legacy"]
            for topic, schema in PROTOBUF_TOPICS.items():
                assert client.channel(topic)["schemaName"] == schema
        bridge.signal(signal.SIGTERM)
        assert bridge.wait(WAIT_S) == 0, bridge.stderr
