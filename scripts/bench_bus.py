"""Benchmark the typed bus against raw zenoh-python + msgpack, across two processes on one machine.

Both paths run in the same invocation, peer to peer over tcp/127.0.0.1, with the same Zenoh
config (common.bus.session.zenoh_config) and the same publisher options (RELIABLE, BLOCK):

- typed: NavFix -> encode -> Publisher.put  ...  Inbox callback -> Inbox.get -> decode
- raw-fifo: dict -> msgpack.packb -> publisher.put  ...  FifoChannel -> recv() -> unpackb
- raw-callback: dict -> msgpack.packb -> publisher.put  ...  unpackb inside the Zenoh callback

Latency is one-way: the sender stamps time.monotonic_ns() (CLOCK_MONOTONIC, system-wide on
Linux) into the payload before building it; the receiver reads the clock once the message is
decoded. Messages are paced by an acknowledgement (identical raw path in every mode), so
latency is measured without queueing. Throughput: the sender publishes as fast as it can; the
rate is n / (last decoded - first stamped). Modes are interleaved over repeats; medians shown.

    .venv/bin/python scripts/bench_bus.py [--lat-n 3000] [--tput-n 50000] [--repeats 3]
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import threading
import time
from dataclasses import dataclass
from typing import Any

import msgpack
import zenoh

from common.bus import Bus, Inbox, Keys, Received
from common.config.bus import BusConfig
from common.messages import NavFix, encode
from common.runtime.procs import free_port

MODES = ("typed", "raw-fifo", "raw-callback")
WAIT_S = 20.0
WARMUP = 200  # latency samples dropped at the start (connection and caches warming up)


def navfix(t_ns: int, seq: int) -> NavFix:
    """The typed payload: a NavFix stamped with the send time (seconds of CLOCK_MONOTONIC)."""
    return NavFix(
        stamp=12.5,
        source="sensor",
        seq=seq,
        sent=t_ns * 1e-9,
        x=10.25,
        y=-3.5,
        heading=0.75,
        speed=1.5,
        std_xy=0.5,
        std_heading=0.0625,
        std_speed=0.125,
    )


def nav_dict(t_ns: int, seq: int) -> dict[str, Any]:
    """The raw payload: the same fields and values as navfix(), as a plain dict."""
    return {
        "stamp": 12.5,
        "source": "sensor",
        "seq": seq,
        "sent": t_ns * 1e-9,
        "x": 10.25,
        "y": -3.5,
        "heading": 0.75,
        "speed": 1.5,
        "std_xy": 0.5,
        "std_heading": 0.0625,
        "std_speed": 0.125,
    }


@dataclass(frozen=True)
class Keyset:
    """The keys of one measurement: data, ack, the receiver's ready token, its done token."""

    keys: Keys

    @property
    def data(self) -> str:
        return self.keys.stream("sender", "nav")

    @property
    def ack(self) -> str:
        return self.keys.stream("receiver", "ack")

    @property
    def ready(self) -> str:
        return self.keys.alive("receiver")

    @property
    def done(self) -> str:
        return self.keys.alive("done")


def _reliable_pub(session: zenoh.Session, key: str) -> Any:
    return session.declare_publisher(
        key,
        reliability=zenoh.Reliability.RELIABLE,
        congestion_control=zenoh.CongestionControl.BLOCK,
    )


def _wait_token(session: zenoh.Session, key: str) -> None:
    """Block until the liveliness token `key` exists (history=True reports an existing one)."""
    seen = threading.Event()

    def on(sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            seen.set()

    sub = session.liveliness().declare_subscriber(key, on, history=True)
    try:
        if not seen.wait(WAIT_S):
            raise TimeoutError(f"no liveliness token {key} within {WAIT_S} s")
    finally:
        sub.undeclare()


# --- the sender (child process) ----------------------------------------------------------------


def sender(mode: str, phase: str, endpoint: str, run: str, n: int) -> None:
    """Publish n messages (latency: each after the previous one's ack), then wait for done."""
    ks = Keyset(Keys(run=run, vehicle="bench"))
    with Bus(BusConfig(connect=(endpoint,)), ks.keys) as bus:
        session = bus.session
        acks = session.declare_subscriber(ks.ack, zenoh.handlers.FifoChannel(16))
        try:
            _wait_token(session, ks.ready)  # declared after the receiver's subscribers
            if mode == "typed":
                pub = bus.publisher("sender", "nav")
                put = lambda i: pub.put(navfix(time.monotonic_ns(), i))  # noqa: E731
            else:
                raw = _reliable_pub(session, ks.data)
                packb = msgpack.packb
                put = lambda i: raw.put(packb(nav_dict(time.monotonic_ns(), i)))  # noqa: E731
            if phase == "latency":
                for i in range(n):
                    put(i)
                    acks.recv()
            else:
                for i in range(n):
                    put(i)
            _wait_token(session, ks.done)  # keep the session until everything is consumed
        finally:
            acks.undeclare()


# --- the receiver (this process) ---------------------------------------------------------------


class Recorder:
    """Per-message bookkeeping, identical in every mode: stamps in, ack out when pacing."""

    def __init__(self, n: int, ack: Any, paced: bool) -> None:
        self.n, self.ack, self.paced = n, ack, paced
        self.sent: list[int] = []
        self.recv: list[int] = []
        self.done = threading.Event()

    def add(self, sent_s: float, recv_ns: int) -> None:
        self.sent.append(round(sent_s * 1e9))
        self.recv.append(recv_ns)
        if self.paced:
            self.ack.put(b"a")
        if len(self.recv) == self.n:
            self.done.set()


@dataclass(frozen=True)
class Result:
    """One measurement: one-way latencies (ns), receive and send rates (msg/s), payload size."""

    latencies_ns: list[int]
    recv_rate: float
    send_rate: float
    size: int


def receive(mode: str, phase: str, n: int) -> Result:
    """Run one measurement against a fresh sender process."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    ks = Keyset(Keys(run=f"b{time.monotonic_ns()}", vehicle="bench"))
    now = time.monotonic_ns
    with Bus(BusConfig(listen=(endpoint,)), ks.keys) as bus:
        session = bus.session
        ack = _reliable_pub(session, ks.ack)
        rec = Recorder(n, ack, paced=phase == "latency")
        inbox = Inbox()
        sub: Any = None
        if mode == "typed":
            bus.subscribe(ks.data, inbox)
        elif mode == "raw-fifo":
            sub = session.declare_subscriber(ks.data, zenoh.handlers.FifoChannel(256))
        else:
            unpackb = msgpack.unpackb

            def on_sample(sample: zenoh.Sample) -> None:
                d = unpackb(sample.payload.to_bytes())
                rec.add(d["sent"], now())

            sub = session.declare_subscriber(ks.data, on_sample)
        token = session.liveliness().declare_token(ks.ready)
        child = subprocess.Popen(
            [sys.executable, __file__, "--child", mode, phase, endpoint, ks.keys.run, str(n)]
        )
        try:
            if mode == "typed":
                for i in range(n):
                    ev = inbox.get(timeout=WAIT_S)
                    t = now()
                    if not isinstance(ev, Received):
                        raise TimeoutError(f"typed: message {i} of {n} did not arrive ({ev!r})")
                    rec.add(ev.msg.sent, t)
            elif mode == "raw-fifo":
                unpackb = msgpack.unpackb
                for _ in range(n):
                    d = unpackb(sub.recv().payload.to_bytes())
                    rec.add(d["sent"], now())
            elif not rec.done.wait(WAIT_S * 3):
                raise TimeoutError(f"raw-callback: {len(rec.recv)} of {n} arrived")
            done_token = session.liveliness().declare_token(ks.done)
            if child.wait(timeout=WAIT_S) != 0:
                raise RuntimeError(f"sender exited with {child.returncode}")
            done_token.undeclare()
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
            token.undeclare()
            if sub is not None:
                sub.undeclare()
            ack.undeclare()
    size = len(encode(navfix(0, 0))) if mode == "typed" else len(msgpack.packb(nav_dict(0, 0)))
    lat = [r - s for s, r in zip(rec.sent, rec.recv, strict=True)]
    span_recv = (rec.recv[-1] - rec.sent[0]) * 1e-9
    span_send = max(1, rec.sent[-1] - rec.sent[0]) * 1e-9
    return Result(lat[WARMUP:], n / span_recv, (n - 1) / span_send, size)


def _pct(xs: list[int], q: float) -> float:
    """q-quantile (0..1) in microseconds."""
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] / 1000.0


def main(lat_n: int, tput_n: int, repeats: int) -> None:
    """Interleave the modes over `repeats` rounds and print medians and typed/raw ratios."""
    p50: dict[str, list[float]] = {m: [] for m in MODES}
    p99: dict[str, list[float]] = {m: [] for m in MODES}
    tput: dict[str, list[float]] = {m: [] for m in MODES}
    sizes: dict[str, int] = {}
    for r in range(repeats):
        for mode in MODES:
            lat = receive(mode, "latency", lat_n + WARMUP)
            sizes[mode] = lat.size
            p50[mode].append(_pct(lat.latencies_ns, 0.50))
            p99[mode].append(_pct(lat.latencies_ns, 0.99))
            res = receive(mode, "throughput", tput_n)
            tput[mode].append(res.recv_rate)
            print(
                f"round {r + 1}/{repeats} {mode:>12}: p50 {p50[mode][-1]:7.1f} us  "
                f"p99 {p99[mode][-1]:7.1f} us  received {res.recv_rate:7.0f} msg/s  "
                f"(sender published at {res.send_rate:7.0f} msg/s)",
                flush=True,
            )
    med = {
        m: (statistics.median(p50[m]), statistics.median(p99[m]), statistics.median(tput[m]))
        for m in MODES
    }
    print(
        f"\none-way latency over {lat_n} paced messages, throughput over {tput_n} messages, "
        f"median of {repeats} rounds"
    )
    print(f"{'mode':>12}  {'bytes':>5}  {'p50 us':>8}  {'p99 us':>8}  {'msg/s':>9}")
    for m in MODES:
        print(f"{m:>12}  {sizes[m]:5d}  {med[m][0]:8.1f}  {med[m][1]:8.1f}  {med[m][2]:9.0f}")
    best_lat = min(("raw-fifo", "raw-callback"), key=lambda m: med[m][0])
    best_tput = max(("raw-fifo", "raw-callback"), key=lambda m: med[m][2])
    lat_ratio = med["typed"][0] / med[best_lat][0]
    p99_ratio = med["typed"][1] / med[best_lat][1]
    tput_ratio = med["typed"][2] / med[best_tput][2]
    print(f"\nagainst the fastest raw pattern (latency: {best_lat}, throughput: {best_tput}):")
    print(
        f"  latency p50 typed/raw = {lat_ratio:.2f}  (target <= 1.2)"
        f"  {'OK' if lat_ratio <= 1.2 else 'MISSED'}"
    )
    print(f"  latency p99 typed/raw = {p99_ratio:.2f}")
    print(
        f"  throughput typed/raw  = {tput_ratio:.2f}  (target >= 0.8)"
        f"  {'OK' if tput_ratio >= 0.8 else 'MISSED'}"
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lat-n", type=int, default=3000, help="paced messages per latency run")
    ap.add_argument("--tput-n", type=int, default=50000, help="messages per throughput run")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median shown)")
    ap.add_argument(
        "--child",
        nargs=5,
        metavar=("MODE", "PHASE", "ENDPOINT", "RUN", "N"),
        help=argparse.SUPPRESS,
    )
    a = ap.parse_args()
    if a.child:
        mode, phase, endpoint, run, n = a.child
        sender(mode, phase, endpoint, run, int(n))
    else:
        main(a.lat_n, a.tput_n, a.repeats)
