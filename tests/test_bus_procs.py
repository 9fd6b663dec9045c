"""The typed bus between real OS processes over Zenoh (tcp/127.0.0.1, peer to peer).

The child is tests/helpers/bus_peer.py. Synchronisation is by liveliness tokens, a readiness
line on stdout and timeouts on every wait; no sleeps. (Plus one fast Inbox test, no Zenoh.)
"""

from __future__ import annotations

import os
import queue
import select
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
from helpers.bus_peer import (
    GARBAGE_STREAM,
    PARENT,
    PEER,
    VEHICLE,
    garbage_navs,
    stream_of,
)
from helpers.samples import one_of_each

from common.bus import Bus, Inbox, Keys, Liveliness, Received
from common.config.bus import BusConfig
from common.runtime.processes.children import free_port

TESTS = Path(__file__).resolve().parent
WAIT_S = 15.0  # generous upper bound for any one wait; the happy path takes well under 1 s


@contextmanager
def child(role: str, endpoint: str, run: str) -> Iterator[subprocess.Popen[str]]:
    """Start the helper in its own process group; on the way out, kill the group if alive."""
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(TESTS), env.get("PYTHONPATH")]))
    env["PYTHONUNBUFFERED"] = "1"
    proc = subprocess.Popen(
        [sys.executable, "-m", "helpers.bus_peer", role, "--endpoint", endpoint, "--run", run],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        env=env,
        start_new_session=True,
    )
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=WAIT_S)
        assert proc.stdout is not None and proc.stderr is not None
        proc.stdout.close()
        proc.stderr.close()


def _finish(proc: subprocess.Popen[str]) -> tuple[int, str]:
    """Wait for the child to exit by itself; its exit code and stderr."""
    try:
        code = proc.wait(timeout=WAIT_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"child still running after {WAIT_S} s")
    assert proc.stderr is not None
    return code, proc.stderr.read()


def _setup(tag: str) -> tuple[str, Keys]:
    port = free_port()
    return f"tcp/127.0.0.1:{port}", Keys(run=f"{tag}{port}", vehicle=VEHICLE)


def _receive(inbox: Inbox, n: int) -> list[Received]:
    """Up to `n` messages, each waited for at most WAIT_S."""
    out: list[Received] = []
    deadline = time.monotonic() + WAIT_S
    while len(out) < n and (left := deadline - time.monotonic()) > 0:
        ev = inbox.get(timeout=left)
        if isinstance(ev, Received):
            out.append(ev)
    return out


@pytest.mark.slow
def test_every_message_type_crosses_between_processes() -> None:
    endpoint, keys = _setup("x")
    expected = {stream_of(type(m)): m for m in one_of_each()}
    with Bus(BusConfig(listen=(endpoint,)), keys) as bus:
        inbox = Inbox()
        bus.subscribe(keys.stream(PEER, "*"), inbox)
        bus.declare_alive(PARENT)  # after subscribing: the child publishes once it sees this
        with child("exchange", endpoint, keys.run) as proc:
            got = _receive(inbox, len(expected))
            by_stream = {keys.split(r.key)[1]: r.msg for r in got}
            assert len(got) == len(expected), f"got {sorted(by_stream)}"
            assert by_stream == expected
            assert inbox.decode_errors == {}
            bus.close()  # withdraws our token: the child's cue to exit
            code, err = _finish(proc)
    assert code == 0, err


@pytest.mark.slow
def test_garbage_is_counted_and_the_next_valid_message_still_arrives() -> None:
    endpoint, keys = _setup("g")
    key = keys.stream(PEER, GARBAGE_STREAM)
    with Bus(BusConfig(listen=(endpoint,)), keys) as bus:
        inbox = Inbox()
        bus.subscribe(key, inbox)
        bus.declare_alive(PARENT)
        with child("garbage", endpoint, keys.run) as proc:
            got = _receive(inbox, 2)
            assert [r.msg for r in got] == garbage_navs()
            # both bad payloads were sent before the second valid one on one session
            deadline = time.monotonic() + WAIT_S
            while inbox.decode_errors.get(key, 0) < 2 and time.monotonic() < deadline:
                inbox.get(timeout=0.1)  # drains (and counts) anything still queued
            assert inbox.decode_errors == {key: 2}
            assert "wrong wire version 99" in inbox.last_error[key]
            bus.close()
            code, err = _finish(proc)
    assert code == 0, err


@pytest.mark.slow
def test_a_typed_callback_counts_garbage_and_survives_its_own_exceptions() -> None:
    endpoint, keys = _setup("c")
    key = keys.stream(PEER, GARBAGE_STREAM)
    got: queue.SimpleQueue[Received] = queue.SimpleQueue()

    def on_message(r: Received) -> None:
        got.put(r)
        if r.msg.seq == garbage_navs()[0].seq:
            raise RuntimeError("a consumer bug")  # logged; the subscription must carry on

    with Bus(BusConfig(listen=(endpoint,)), keys) as bus:
        handler = bus.subscribe_typed(key, on_message)
        bus.declare_alive(PARENT)
        with child("garbage", endpoint, keys.run) as proc:
            msgs = [got.get(timeout=WAIT_S).msg for _ in garbage_navs()]
            assert msgs == garbage_navs()
            # both bad payloads came before the second valid one on one session, and the
            # callback runs in arrival order: they are counted by now
            assert handler.decode_errors == {key: 2}
            assert "wrong wire version 99" in handler.last_error[key]
            assert "not a tidelink" not in handler.last_error[key]
            bus.close()
            code, err = _finish(proc)
    assert code == 0, err


def _read_line(proc: subprocess.Popen[str], timeout_s: float) -> str:
    assert proc.stdout is not None
    ready, _, _ = select.select([proc.stdout], [], [], timeout_s)
    return proc.stdout.readline().strip() if ready else ""


@pytest.mark.slow
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT], ids=["SIGTERM", "SIGINT"])
def test_a_process_with_open_subscribers_exits_promptly_on_a_signal(sig: signal.Signals) -> None:
    endpoint, keys = _setup("s")
    with child("idle", endpoint, keys.run) as proc:
        line = _read_line(proc, WAIT_S)
        assert line == "ready", f"no readiness line (got {line!r}); exit code {proc.poll()}"
        with Bus(BusConfig(connect=(endpoint,)), keys) as bus:
            inbox = Inbox()
            bus.watch_alive(inbox, keys.alive(PEER))
            ev = inbox.get(timeout=WAIT_S)
            assert ev == Liveliness(keys.alive(PEER), True)  # connected: the child is live
            # traffic into the child's inbox and callback subscribers while it runs
            pub = bus.publisher(PARENT, "nav")
            for msg in one_of_each()[:3]:
                pub.put(msg)
            # "promptly" is a liveness bound (a hang fails after WAIT_S), not a speed claim:
            # how fast the exit is belongs in a benchmark, not in a test on a loaded machine
            t0 = time.monotonic()
            proc.send_signal(sig)
            try:
                code = proc.wait(timeout=WAIT_S)
            except subprocess.TimeoutExpired:
                pytest.fail(f"no exit within {WAIT_S} s of {sig.name}")
            gone = inbox.get(timeout=WAIT_S)
            gone_s = time.monotonic() - t0
        assert proc.stderr is not None
        err = proc.stderr.read()
    assert code == 0, f"exit code {code} after {sig.name}; stderr:\n{err}"
    # and the token was withdrawn (Bus closed on the way out, not only the process killed)
    assert gone == Liveliness(keys.alive(PEER), False), f"{gone!r} after {gone_s:.3f} s"


class _GarbageTrickle:
    """Stands in for the Inbox queue: garbage arrives after half of any wait; none is queued."""

    def __init__(self, clock: list[float]) -> None:
        self.clock = clock
        self.calls = 0
        self.delivered = 0

    def put(self, item: object) -> None:
        raise AssertionError("no subscription feeds this inbox")

    def get(self, timeout: float | None = None) -> tuple[str, bytes, None]:
        self.calls += 1
        assert self.calls < 1000, "Inbox.get keeps waiting while garbage trickles in"
        assert timeout is not None, "Inbox.get lost its timeout"
        if timeout <= 0.0:
            raise queue.Empty  # nothing is waiting right now
        self.clock[0] += timeout / 2 + 1e-3
        self.delivered += 1
        return ("tidelink/r/v/peer/nav", b"\xc1", None)


@contextmanager
def router(endpoint: str) -> Iterator[subprocess.Popen[str]]:
    """`tidelink router` listening on `endpoint`, its ready line read; killed on the way out."""
    proc = subprocess.Popen(
        [sys.executable, "-m", "services.cli", "router", "--listen", endpoint, "--insecure"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
    )
    try:
        assert proc.stdout is not None
        ready, _, _ = select.select([proc.stdout], [], [], WAIT_S)
        assert ready and "listening on" in proc.stdout.readline()
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(timeout=WAIT_S)
        assert proc.stdout is not None
        proc.stdout.close()


def _until(what: str, cond: Callable[[], bool]) -> None:
    deadline = time.monotonic() + WAIT_S
    while not cond():
        assert time.monotonic() < deadline, f"not {what} within {WAIT_S} s"
        time.sleep(0.02)  # polling Bus.connected(), the state a realtime service itself reads


@pytest.mark.slow
def test_a_client_knows_when_it_is_cut_off_from_its_router_and_rejoins_one_that_returns() -> None:
    # a realtime service tells "the launcher is gone" from "I am cut off" by this: cut off,
    # every token it saw vanishes with its router, the clock's too (realtime_service.py)
    endpoint, keys = _setup("c")
    with router(endpoint) as first:
        with Bus(BusConfig(mode="client", connect=(endpoint,)), keys) as bus:
            _until("connected", bus.connected)
            first.kill()
            first.wait(timeout=WAIT_S)
            _until("cut off", lambda: not bus.connected())
            with router(endpoint):  # a router back on the same endpoint: the client retries
                _until("reconnected", bus.connected)


def test_inbox_get_honours_its_timeout_while_garbage_trickles_in() -> None:
    clock = [100.0]
    fake = _GarbageTrickle(clock)
    inbox = Inbox(clock=lambda: clock[0], fifo=fake)  # type: ignore[arg-type]
    assert inbox.get(timeout=1.0) is None
    assert clock[0] - 100.0 <= 1.0 + 2e-3  # gave up at the deadline, not after it
    assert fake.delivered >= 5
    assert inbox.decode_errors == {"tidelink/r/v/peer/nav": fake.delivered}


def test_what_an_inbox_holds_when_its_bus_closes_is_still_delivered() -> None:
    # the inbox queues Zenoh samples; closing the bus turns them into plain data (no Zenoh
    # object may outlive the session) without losing or reordering any
    keys = Keys(run=f"d{os.getpid()}", vehicle=VEHICLE)
    msgs = one_of_each()[:3]
    inbox = Inbox()
    with Bus(BusConfig(), keys) as bus:
        bus.subscribe(keys.stream(PEER, "*"), inbox)
        for m in msgs:
            bus.publisher(PEER, stream_of(type(m))).put(m)
        deadline = time.monotonic() + WAIT_S
        while inbox.pending() < len(msgs):
            assert time.monotonic() < deadline, f"{inbox.pending()} of {len(msgs)} queued"
            time.sleep(0.01)  # local delivery runs on Zenoh's callback thread
    # the bus is closed: what it held is still there, in order, and decodes
    assert inbox.pending() == len(msgs)
    got = [inbox.get(timeout=0) for _ in msgs]
    assert [r.msg for r in got if isinstance(r, Received)] == msgs
    assert inbox.get(timeout=0) is None
