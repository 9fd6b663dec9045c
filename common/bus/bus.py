"""The typed bus: publish and subscribe tidelink messages over one Zenoh session."""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import deque
from collections.abc import Callable, Mapping
from types import TracebackType
from typing import Any, NamedTuple

import msgspec
import zenoh

from common.bus.keys import Keys
from common.bus.session import open_session
from common.config.bus import BusConfig
from common.messages import Message, WireError, decode, encode

log = logging.getLogger("tidelink.bus")


# Events are frozen msgspec structs rather than frozen dataclasses: one is built per message
# received, and a struct builds an order of magnitude faster.


class Received(msgspec.Struct, frozen=True, gc=False):
    """A decoded message and where it came from."""

    key: str
    msg: Message
    attachment: bytes | None


class Liveliness(msgspec.Struct, frozen=True, gc=False):
    """A liveliness token appeared (alive=True) or vanished (alive=False)."""

    key: str
    alive: bool


Event = Received | Liveliness


class _Rejects:
    """Counts undecodable payloads per key and logs the first of each key; never raises."""

    def __init__(self) -> None:
        self.decode_errors: dict[str, int] = {}
        self.last_error: dict[str, str] = {}

    def _reject(self, key: str, why: str) -> None:
        n = self.decode_errors.get(key, 0) + 1
        self.decode_errors[key] = n
        self.last_error[key] = why
        if n == 1:
            log.warning(
                "dropping undecodable payload on %s: %s (further ones only counted)", key, why
            )


class RawFrame(NamedTuple):
    """A sample as plain data: its key, the encoded payload and attachment as they crossed
    the wire (what a closed bus leaves in an inbox, what recorders store)."""

    key: str
    payload: bytes
    attachment: bytes | None


def _plain(sample: zenoh.Sample) -> RawFrame:
    """The key, payload and attachment of a Zenoh sample, as plain Python data."""
    att = sample.attachment
    return RawFrame(
        str(sample.key_expr), sample.payload.to_bytes(), None if att is None else att.to_bytes()
    )


_Item = zenoh.Sample | RawFrame | Liveliness


def _key_of(item: _Item) -> str:
    if isinstance(item, RawFrame | Liveliness):
        return item.key
    return str(item.key_expr)


class Inbox(_Rejects):
    """One queue that every subscription of a process feeds; the process's loop drains it.

    A Zenoh callback only enqueues the sample itself (SimpleQueue.put, a C call: no Python
    frame on Zenoh's thread, so it holds the GIL as briefly as possible); reading the key,
    payload and attachment, and decoding, happen in `get`, on the caller's thread. When the
    bus closes, samples still queued are turned into plain data (`detach`), so no Zenoh
    object outlives the session. Payloads that fail to decode are counted per key and
    logged once per key; the inbox carries on with the next sample.

    With `max_pending`, a loop that cannot keep up (a flood) does not fall ever further
    behind: when more than max_pending events wait, `get` sheds the oldest samples first,
    down to half, keeping every liveliness event and every sample whose key `keep` accepts
    (a clock's ticks); `on_shed(key, n)` is told what was shed. Without it nothing is ever
    dropped (a lockstep service must see every message).
    """

    def __init__(
        self,
        *,
        clock: Callable[[], float] = time.monotonic,
        fifo: queue.SimpleQueue[Any] | None = None,
        max_pending: int | None = None,
        keep: Callable[[str], bool] = lambda key: False,
        on_shed: Callable[[str, int], None] = lambda key, n: None,
    ) -> None:
        # clock and fifo are seams for tests (a fake clock, a queue that trickles)
        super().__init__()
        self._clock = clock
        self._q: queue.SimpleQueue[_Item] = queue.SimpleQueue() if fifo is None else fifo
        self._on_sample: Callable[[zenoh.Sample], None] = self._q.put
        self._max_pending = max_pending
        self._keep = keep
        self._on_shed = on_shed
        self._backlog: deque[_Item] = deque()  # survivors of a shed, taken before the queue
        self.shed: dict[str, int] = {}  # key -> samples shed

    def pending(self) -> int:
        """Events queued and not yet taken (valid or not: decoding happens in `get`)."""
        return self._q.qsize() + len(self._backlog)

    def _drain(self) -> list[_Item]:
        items = list(self._backlog)
        self._backlog.clear()
        while True:
            try:
                item = self._q.get_nowait()
            except queue.Empty:
                return items
            items.append(item)

    def detach(self) -> None:
        """Replace the queued Zenoh samples by plain data, keeping their order."""
        for item in self._drain():
            self._backlog.append(item if isinstance(item, Liveliness | RawFrame) else _plain(item))

    def _shed(self) -> None:
        """Drop the oldest samples, down to max_pending / 2, keeping the precious events."""
        assert self._max_pending is not None
        items = self._drain()
        excess = len(items) - self._max_pending // 2
        shed: dict[str, int] = {}
        for item in items:
            if excess > 0 and not isinstance(item, Liveliness):
                key = _key_of(item)
                if not self._keep(key):
                    shed[key] = shed.get(key, 0) + 1
                    excess -= 1
                    continue
            self._backlog.append(item)
        for key, n in shed.items():
            self.shed[key] = self.shed.get(key, 0) + n
            self._on_shed(key, n)

    def _take(self, deadline: float | None) -> _Item | None:
        """The next queued event (survivors of a shed first), waiting until the deadline."""
        if self._max_pending is not None and self.pending() > self._max_pending:
            self._shed()
        if self._backlog:
            return self._backlog.popleft()
        try:
            if deadline is None:
                return self._q.get()
            return self._q.get(timeout=max(0.0, deadline - self._clock()))
        except queue.Empty:
            return None

    def get(self, timeout: float | None = None) -> Event | None:
        """The next valid event, or None when `timeout` seconds pass with nothing valid."""
        # One deadline for the whole call: a trickle of undecodable payloads must not keep
        # restarting the wait (the caller's step would never come).
        deadline = None if timeout is None else self._clock() + timeout
        item = self._take(deadline)
        if item is None:
            return None
        while True:
            if isinstance(item, Liveliness):
                return item
            # a tuple (RawFrame) was queued when the bus closed; the rest are Zenoh samples
            key, payload, att = item if isinstance(item, tuple) else _plain(item)
            try:
                return Received(key, decode(payload), att)
            except WireError as exc:
                self._reject(key, str(exc))
            item = self._take(deadline)
            if item is None:
                return None


class TypedCallback(_Rejects):
    """Decodes each sample on Zenoh's callback thread and hands the message to a function.

    For consumers that record or display rather than step a loop (monitors, recorders):
    one thread switch less than an Inbox. Undecodable payloads are counted like an Inbox's;
    an exception from the function is logged and the subscription carries on.
    """

    def __init__(self, on_message: Callable[[Received], None]) -> None:
        super().__init__()
        self._on_message = on_message

    def __call__(self, sample: zenoh.Sample) -> None:
        key, payload, att = _plain(sample)
        try:
            msg = decode(payload)
        except WireError as exc:
            self._reject(key, str(exc))
            return
        try:
            self._on_message(Received(key, msg, att))
        except Exception:  # noqa: BLE001 - one bad message must not end the subscription
            log.exception("subscriber callback failed on %s", key)


class Publisher:
    """Publishes one stream's messages reliably (our network model is the only loss)."""

    def __init__(self, pub: Any, key: str) -> None:
        self._pub = pub
        self.key = key

    def put(self, msg: Message, attachment: bytes | None = None) -> int:
        """Encode and send; returns the payload size in bytes."""
        data = encode(msg)
        self.put_bytes(data, attachment)
        return len(data)

    def put_bytes(self, data: bytes, attachment: bytes | None = None) -> None:
        """Send an already encoded payload (used by runtimes that needed the size first)."""
        if attachment is None:
            self._pub.put(data)  # an explicit attachment=None costs zenoh-python a conversion
        else:
            self._pub.put(data, attachment=attachment)


class Bus:
    """A Zenoh session plus every declaration made through it, closed together on exit."""

    def __init__(
        self,
        cfg: BusConfig,
        keys: Keys,
        *,
        low_latency: bool = False,
        identity: str | None = None,
        access_control: Mapping[str, object] | None = None,
    ) -> None:
        self.cfg = cfg
        self.keys = keys
        # under mTLS: whose certificate this session presents; a router may also enforce an
        # access control (docs/security.md)
        self.identity = identity
        self.access_control = access_control
        # low_latency: subscription callbacks run on Zenoh's network thread instead of being
        # handed to a Python thread first: one thread switch less per message, but throughput
        # suffers when messages come back to back
        self.low_latency = low_latency
        self._session: zenoh.Session | None = None
        self._declared: list[Any] = []
        self._inboxes: list[Inbox] = []  # fed by this bus: detached from Zenoh when it closes
        self._lock = threading.Lock()

    def __enter__(self) -> Bus:
        self._session = open_session(
            self.cfg, identity=self.identity, access_control=self.access_control
        )
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    @property
    def session(self) -> zenoh.Session:
        if self._session is None:
            raise RuntimeError("bus is not open (use `with Bus(...) as bus:`)")
        return self._session

    def close(self) -> None:
        """Undeclare everything, then close the session (a left-open callback hangs exit)."""
        with self._lock:
            declared, self._declared = self._declared, []
            inboxes, self._inboxes = self._inboxes, []
            session, self._session = self._session, None
        for obj in reversed(declared):
            try:
                obj.undeclare()
            except Exception as exc:  # noqa: BLE001 - closing must go on whatever one object says
                log.debug("undeclare failed: %s", exc)
        for inbox in inboxes:
            inbox.detach()
        if session is not None:
            session.close()
        for inbox in inboxes:  # anything a callback thread was still handing over
            inbox.detach()

    def _keep(self, obj: Any) -> Any:
        with self._lock:
            self._declared.append(obj)
        return obj

    def publisher(self, service: str, stream: str, *, express: bool = False) -> Publisher:
        """A publisher of one service's output stream."""
        return self.publisher_on(self.keys.stream(service, stream), express=express)

    def publisher_on(self, key: str, *, express: bool = False) -> Publisher:
        """A publisher on any key of this run (e.g. Keys.tick): the control path's settings,
        reliable and blocking, so that loss comes only from our network model."""
        pub = self.session.declare_publisher(
            key,
            reliability=zenoh.Reliability.RELIABLE,  # zenoh-python's default is best-effort
            congestion_control=zenoh.CongestionControl.BLOCK,
            express=express,
        )
        return Publisher(self._keep(pub), key)

    def monitoring_publisher(self, key: str, *, last: bool = False) -> Publisher:
        """A publisher for watchers outside the control loop (Keys.watch): congestion DROP
        and priority DATA_LOW. A router forwards a BLOCK sample to a subscriber that stopped
        reading by waiting, stalling the publisher and every other subscriber; a DROP sample
        is dropped for that subscriber alone, so no watcher can slow the run
        (docs/monitoring.md, docs/notes/0002-watch-tap-drop-copies.md).

        `last`: BLOCK instead, for the one message a run sends after its loop is over (the
        RunEnd), which a slow watcher must not lose: behind a stopped subscriber a DROP one
        can reach no subscriber at all (docs/notes/code-run-end-published-block.md). Same
        priority: it still comes after the copies sent before it."""
        congestion = zenoh.CongestionControl.BLOCK if last else zenoh.CongestionControl.DROP
        pub = self.session.declare_publisher(
            key,
            reliability=zenoh.Reliability.RELIABLE,
            congestion_control=congestion,
            priority=zenoh.Priority.DATA_LOW,
        )
        return Publisher(self._keep(pub), key)

    def subscribe(self, key_expr: str, inbox: Inbox) -> None:
        """Feed every sample on `key_expr` into `inbox` (decoded when the loop takes it)."""
        handler = zenoh.handlers.Callback(inbox._on_sample, indirect=not self.low_latency)
        self._keep(self.session.declare_subscriber(key_expr, handler))
        with self._lock:
            if inbox not in self._inboxes:
                self._inboxes.append(inbox)

    def subscribe_stream(self, service: str, stream: str, inbox: Inbox) -> None:
        self.subscribe(self.keys.stream(service, stream), inbox)

    def subscribe_typed(
        self, key_expr: str, on_message: Callable[[Received], None]
    ) -> TypedCallback:
        """Decoded messages on `key_expr` to a function, called on Zenoh's callback thread."""
        handler = TypedCallback(on_message)
        self._keep(self.session.declare_subscriber(key_expr, handler))
        return handler

    def subscribe_raw(self, key_expr: str, callback: Callable[[RawFrame], None]) -> None:
        """Every sample on `key_expr`, undecoded, to a callback on Zenoh's thread (taps and
        recorders: keep what crossed the wire). An exception from the callback is logged."""

        def on_sample(sample: zenoh.Sample) -> None:
            try:
                callback(_plain(sample))
            except Exception:  # noqa: BLE001 - one bad sample must not end the subscription
                log.exception("raw subscriber failed on %s", sample.key_expr)

        self._keep(self.session.declare_subscriber(key_expr, on_sample))

    def declare_alive(self, service: str) -> None:
        """Declare this process's liveliness token, withdrawn when the bus closes or dies."""
        self._keep(self.session.liveliness().declare_token(self.keys.alive(service)))

    def watch_alive(self, inbox: Inbox, key_expr: str | None = None) -> None:
        """Liveliness events (with history: tokens already present are reported) into inbox."""
        self.on_alive(key_expr or self.keys.all_alive, inbox._q.put)

    def on_alive(self, key_expr: str, callback: Callable[[Liveliness], None]) -> None:
        """Liveliness events on `key_expr` to a callback on Zenoh's thread (with history)."""

        def on_sample(sample: zenoh.Sample) -> None:
            callback(Liveliness(str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))

        sub = self.session.liveliness().declare_subscriber(key_expr, on_sample, history=True)
        self._keep(sub)

    def connected(self) -> bool:
        """Whether this session has a transport to any router or peer now: a client whose
        host is cut off has none (after its lease), and every token it saw vanished with it,
        whether or not their owners are still there."""
        info = self.session.info
        return bool(info.routers_zid()) or bool(info.peers_zid())

    def alive_now(self, key_expr: str, *, timeout_s: float = 1.0) -> list[str]:
        """The liveliness tokens present on `key_expr` now (a query, answered within
        timeout_s): what a tool that has just joined a run reports before any event."""
        replies = self.session.liveliness().get(key_expr, timeout=timeout_s)
        return sorted(str(r.ok.key_expr) for r in replies if r.ok is not None)

    def put_raw(self, key: str, data: bytes) -> None:
        """Publish raw bytes on a key (tools and tests that must send arbitrary payloads)."""
        self.session.put(key, data)

    def serve(self, key: str, answer: Callable[[], bytes], *, encoding: str) -> None:
        """Answer every query on `key` with `answer()` (a queryable, so a tool that joins at
        any time can ask what a run is, e.g. its declared dataflow)."""

        def on_query(query: zenoh.Query) -> None:
            try:
                query.reply(key, answer(), encoding=zenoh.Encoding(encoding))
            except Exception as exc:  # noqa: BLE001 - a callback must not die silently
                log.warning("queryable %s could not answer: %s", key, exc)

        self._keep(self.session.declare_queryable(key, on_query))

    def serve_frames(
        self, key_expr: str, answer: Callable[[str, dict[str, str]], list[RawFrame]]
    ) -> None:
        """Answer queries on `key_expr` with frames: `answer(selector key, parameters)` gives
        the (key, payload, attachment) of each reply (e.g. the newest frame of every stream)."""

        def on_query(query: zenoh.Query) -> None:
            try:
                params = {str(k): str(v) for k, v in query.parameters}  # type: ignore[attr-defined]
                for f in answer(str(query.key_expr), params):
                    if f.attachment is None:
                        query.reply(f.key, f.payload)
                    else:
                        query.reply(f.key, f.payload, attachment=f.attachment)
            except Exception as exc:  # noqa: BLE001 - a callback must not die silently
                log.warning("queryable %s could not answer: %s", key_expr, exc)

        self._keep(self.session.declare_queryable(key_expr, on_query))

    def query(self, selector: str, *, timeout_s: float) -> list[RawFrame]:
        """Every reply to a query on `selector` within timeout_s, as raw frames.

        Queries come from tools, never from the control loop: they go DROP / DATA_LOW (and
        their replies with them), so a tool that stops reading cannot stall the answerer.
        """
        out = []
        replies = self.session.get(
            selector,
            timeout=timeout_s,
            congestion_control=zenoh.CongestionControl.DROP,
            priority=zenoh.Priority.DATA_LOW,
            consolidation=zenoh.ConsolidationMode.NONE,
        )
        for reply in replies:
            if reply.ok is not None:
                out.append(_plain(reply.ok))
            else:
                log.warning("query %s: error reply %s", selector, reply.err)
        return out
