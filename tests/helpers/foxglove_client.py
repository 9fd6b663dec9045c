"""A Foxglove WebSocket client for tests, written from the protocol (subprotocol
foxglove.sdk.v1, or foxglove.websocket.v1 as ws-protocol's clients offer it) with the
`websockets` package, independent of the SDK that serves.

Text frames are JSON operations (serverInfo, advertise, unadvertise, status, ...); a binary
frame with opcode 1 is a message: u8 opcode, u32 subscription id, u64 log time (ns), payload,
little-endian. The client subscribes to every channel it is told of, as the app does.
"""

from __future__ import annotations

import base64
import json
import struct
import time
from collections.abc import Callable
from contextlib import ExitStack
from types import TracebackType
from typing import Any, NamedTuple

from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect
from websockets.typing import Subprotocol

SUBPROTOCOL = "foxglove.sdk.v1"
LEGACY_SUBPROTOCOL = "foxglove.websocket.v1"  # the protocol's first name (foxglove/ws-protocol)
MESSAGE_DATA = 1  # binary opcode of a message


class Received(NamedTuple):
    topic: str
    log_time_ns: int
    data: bytes


class FoxgloveClient:
    """Connects, follows advertisements, subscribes to everything, collects messages."""

    def __init__(
        self, url: str, *, open_timeout_s: float = 10.0, subprotocol: str = SUBPROTOCOL
    ) -> None:
        self._stack = ExitStack()
        self.ws: ClientConnection = self._stack.enter_context(
            connect(
                url,
                subprotocols=[Subprotocol(subprotocol)],
                open_timeout=open_timeout_s,
                max_size=None,
            )
        )
        self.server_infos: list[dict[str, Any]] = []
        self.statuses: list[dict[str, Any]] = []
        self.channels: dict[int, dict[str, Any]] = {}  # advertised channel id -> channel
        self.advertised_topics: set[str] = set()
        self._subs: dict[int, int] = {}  # subscription id -> channel id
        self._next_sub = 1
        self.messages: list[Received] = []
        self.ops: list[str] = []  # every text operation, in short: what a failure shows
        self.unrouted: dict[int, int] = {}  # message frames whose subscription id is not ours
        self.closed = False

    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self._stack.close()

    @property
    def subprotocol(self) -> str | None:
        return self.ws.subprotocol

    def channel(self, topic: str) -> dict[str, Any]:
        """The advertised channel of a topic (the newest advertisement)."""
        found = [c for c in self.channels.values() if c["topic"] == topic]
        assert found, f"{topic} was never advertised; topics: {sorted(self.advertised_topics)}"
        return found[-1]

    def on(self, topic: str) -> list[Received]:
        return [m for m in self.messages if m.topic == topic]

    def pump(self, timeout_s: float) -> None:
        """Handle frames for up to timeout_s (returns at the first gap that long)."""
        try:
            frame = self.ws.recv(timeout=timeout_s)
        except TimeoutError:
            return
        except ConnectionClosed:
            self.closed = True
            return
        if isinstance(frame, bytes):
            self._binary(frame)
        else:
            self._op(json.loads(frame))

    def wait_until(self, cond: Callable[[], bool], timeout_s: float, what: str) -> None:
        """Pump until cond() holds; AssertionError naming `what` after timeout_s."""
        deadline = time.monotonic() + timeout_s
        while not cond():
            left = deadline - time.monotonic()
            if left <= 0 or self.closed:
                topics = sorted(self.advertised_topics)
                raise AssertionError(
                    f"no {what} within {timeout_s} s (closed={self.closed}); advertised: {topics}"
                )
            self.pump(min(left, 0.5))

    def _op(self, msg: dict[str, Any]) -> None:
        op = msg.get("op")
        self.ops.append(_short(msg))
        if op == "serverInfo":
            self.server_infos.append(msg)
        elif op == "status":
            self.statuses.append(msg)
        elif op == "advertise":
            subs = []
            for ch in msg["channels"]:
                self.channels[ch["id"]] = ch
                self.advertised_topics.add(ch["topic"])
                sid = self._next_sub
                self._next_sub += 1
                self._subs[sid] = ch["id"]
                subs.append({"id": sid, "channelId": ch["id"]})
            if subs:
                self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))
                self.ops.append(f"(sent) subscribe {[(x['id'], x['channelId']) for x in subs]}")
        elif op == "unadvertise":
            for cid in msg["channelIds"]:
                self.channels.pop(cid, None)

    def _binary(self, frame: bytes) -> None:
        if frame[0] != MESSAGE_DATA:
            return  # time, service responses, ...: not used here
        sub_id, log_time = struct.unpack_from("<IQ", frame, 1)
        channel = self.channels.get(self._subs.get(sub_id, -1))
        if channel is not None:
            self.messages.append(Received(channel["topic"], log_time, frame[13:]))
        else:
            self.unrouted[sub_id] = self.unrouted.get(sub_id, 0) + 1


def _short(msg: dict[str, Any]) -> str:
    """A text operation in one line: its op and what names it (no schemas)."""
    op = msg.get("op")
    if op == "advertise":
        return f"advertise {[(c['id'], c['topic']) for c in msg['channels']]}"
    if op == "serverInfo":
        return f"serverInfo {msg.get('sessionId')}"
    if op == "status":
        return f"status {msg.get('level')} {msg.get('message')!r}"
    return json.dumps({k: v for k, v in msg.items() if k != "schema"})[:200]


def schema_bytes(channel: dict[str, Any]) -> bytes:
    """An advertised channel's schema as bytes: a protobuf FileDescriptorSet travels base64."""
    if channel.get("schemaEncoding") == "protobuf" or channel["encoding"] == "protobuf":
        return base64.b64decode(channel["schema"])
    return str(channel["schema"]).encode()
