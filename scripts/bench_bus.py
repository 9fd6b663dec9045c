"""Benchmark the typed bus against raw zenoh-python + msgpack, across two processes on one machine.

Both paths run in the same invocation, peer to peer over tcp/127.0.0.1, with the same Zenoh
config (Bus/zenoh_config) and the same publisher options (RELIABLE, BLOCK, and express as
Bus.publisher's default unless --express/--batched says otherwise):

- typed: NavFix -> encode -> Publisher.put  ...  Inbox callback -> Inbox.get -> decode
- raw-fifo: dict -> msgpack.packb -> publisher.put  ...  FifoChannel -> recv() -> unpackb
- raw-callback: dict -> msgpack.packb -> publisher.put  ...  unpackb inside the Zenoh callback

Latency is one-way: the sender stamps time.monotonic_ns() (CLOCK_MONOTONIC, system-wide on
Linux) into the payload before building it; the receiver reads the clock once the message is
decoded. Messages are paced by an acknowledgement (identical raw path in every mode), so
latency is measured without queueing. Throughput: the sender publishes as fast as it can; the
rate is n / (last decoded - first stamped). Each process also reports its CPU time per message
(all its threads), which is far less sensitive to other load on the machine than the rates.
Modes are interleaved over rounds; medians are shown. The load average is printed: on a busy
machine the rates and latencies mean little.

    .venv/bin/python scripts/bench_bus.py [--lat-n 3000] [--tput-n 50000] [--repeats 3]
        [--express | --batched] [--diagnose]
"""

from __future__ import annotations

import argparse
import inspect
import os
import queue
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
from common.messages import NavFix, decode, encode
from common.runtime.procs import free_port

MODES = ("typed", "raw-fifo", "raw-callback")
# --diagnose adds two rows that split the typed/raw gap into its two causes:
# typed-pull: typed sender, receiver pulls from a FifoChannel and decodes (codec cost, no handoff);
# raw-queue: raw sender, receiver hands off through a Python callback and a SimpleQueue to the
#            loop, as Inbox does (handoff cost, no codec).
DIAGNOSTIC = ("typed-pull", "raw-queue")
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


def _reliable_pub(session: zenoh.Session, key: str, express: bool = False) -> Any:
    return session.declare_publisher(
        key,
        reliability=zenoh.Reliability.RELIABLE,
        congestion_control=zenoh.CongestionControl.BLOCK,
        express=express,
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


def sender(mode: str, phase: str, endpoint: str, run: str, n: int, express: bool) -> None:
    """Publish n messages (latency: each after the previous one's ack), then wait for done."""
    ks = Keyset(Keys(run=run, vehicle="bench"))
    with Bus(BusConfig(connect=(endpoint,)), ks.keys) as bus:
        session = bus.session
        acks = session.declare_subscriber(ks.ack, zenoh.handlers.FifoChannel(16))
        try:
            _wait_token(session, ks.ready)  # declared after the receiver's subscribers
            if mode.startswith("typed"):
                pub = bus.publisher("sender", "nav", express=express)
                put = lambda i: pub.put(navfix(time.monotonic_ns(), i))  # noqa: E731
            else:
                raw = _reliable_pub(session, ks.data, express)
                packb = msgpack.packb
                put = lambda i: raw.put(packb(nav_dict(time.monotonic_ns(), i)))  # noqa: E731
            cpu0 = time.process_time()  # every thread of this process, Zenoh's included
            if phase == "latency":
                for i in range(n):
                    put(i)
                    acks.recv()
            else:
                for i in range(n):
                    put(i)
            print(f"cpu_s {time.process_time() - cpu0}", flush=True)
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
    """One measurement: one-way latencies (ns), rates (msg/s), CPU per message (us), size."""

    latencies_ns: list[int]
    recv_rate: float
    send_rate: float
    send_cpu_us: float
    recv_cpu_us: float
    size: int


def receive(mode: str, phase: str, n: int, express: bool) -> Result:
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
        elif mode in ("raw-fifo", "typed-pull"):
            sub = session.declare_subscriber(ks.data, zenoh.handlers.FifoChannel(256))
        elif mode == "raw-queue":
            handoff: queue.SimpleQueue[bytes] = queue.SimpleQueue()
            sub = session.declare_subscriber(
                ks.data, lambda sample: handoff.put(sample.payload.to_bytes())
            )
        else:
            unpackb = msgpack.unpackb

            def on_sample(sample: zenoh.Sample) -> None:
                d = unpackb(sample.payload.to_bytes())
                rec.add(d["sent"], now())

            sub = session.declare_subscriber(ks.data, on_sample)
        token = session.liveliness().declare_token(ks.ready)
        cpu0 = time.process_time()
        child = subprocess.Popen(
            [sys.executable, __file__, "--child", mode, phase, endpoint, ks.keys.run, str(n)]
            + (["--express"] if express else ["--batched"]),
            stdout=subprocess.PIPE,
            text=True,
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
            elif mode == "typed-pull":
                for _ in range(n):
                    msg = decode(sub.recv().payload.to_bytes())
                    rec.add(msg.sent, now())
            elif mode == "raw-queue":
                unpackb = msgpack.unpackb
                for _ in range(n):
                    d = unpackb(handoff.get(timeout=WAIT_S))
                    rec.add(d["sent"], now())
            elif not rec.done.wait(WAIT_S * 3):
                raise TimeoutError(f"raw-callback: {len(rec.recv)} of {n} arrived")
            recv_cpu_s = time.process_time() - cpu0
            done_token = session.liveliness().declare_token(ks.done)
            out, _ = child.communicate(timeout=WAIT_S)
            if child.returncode != 0:
                raise RuntimeError(f"sender exited with {child.returncode}")
            done_token.undeclare()
            send_cpu_s = float(out.split()[-1])
        finally:
            if child.poll() is None:
                child.kill()
                child.wait()
            token.undeclare()
            if sub is not None:
                sub.undeclare()
            ack.undeclare()
    size = (
        len(encode(navfix(0, 0)))
        if mode.startswith("typed")
        else len(msgpack.packb(nav_dict(0, 0)))
    )
    lat = [r - s for s, r in zip(rec.sent, rec.recv, strict=True)]
    span_recv = (rec.recv[-1] - rec.sent[0]) * 1e-9
    span_send = max(1, rec.sent[-1] - rec.sent[0]) * 1e-9
    return Result(
        latencies_ns=lat[WARMUP:],
        recv_rate=n / span_recv,
        send_rate=(n - 1) / span_send,
        send_cpu_us=send_cpu_s / n * 1e6,
        recv_cpu_us=recv_cpu_s / n * 1e6,
        size=size,
    )


def _pct(xs: list[int], q: float) -> float:
    """q-quantile (0..1) in microseconds."""
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] / 1000.0


COLUMNS = {  # metric: (header, format)
    "p50": ("p50 us", "{:8.1f}"),
    "p99": ("p99 us", "{:8.1f}"),
    "rate": ("msg/s", "{:8.0f}"),
    "send_cpu": ("tx cpu us", "{:9.2f}"),
    "recv_cpu": ("rx cpu us", "{:9.2f}"),
}


def main(lat_n: int, tput_n: int, repeats: int, diagnose: bool, express: bool) -> None:
    """Interleave the modes over `repeats` rounds and print medians and typed/raw ratios."""
    modes = MODES + DIAGNOSTIC if diagnose else MODES
    got: dict[str, dict[str, list[float]]] = {m: {k: [] for k in COLUMNS} for m in modes}
    sizes: dict[str, int] = {}
    print(
        f"publishers (typed and raw alike): RELIABLE, BLOCK, express={express}; "
        f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs",
        flush=True,
    )
    for r in range(repeats):
        for mode in modes:
            lat = receive(mode, "latency", lat_n + WARMUP, express)
            res = receive(mode, "throughput", tput_n, express)
            sizes[mode] = lat.size
            row = {
                "p50": _pct(lat.latencies_ns, 0.50),
                "p99": _pct(lat.latencies_ns, 0.99),
                "rate": res.recv_rate,
                "send_cpu": res.send_cpu_us,
                "recv_cpu": res.recv_cpu_us,
            }
            for k, v in row.items():
                got[mode][k].append(v)
            print(
                f"round {r + 1}/{repeats} {mode:>12}: "
                + "  ".join(f"{COLUMNS[k][0]} {v:.1f}" for k, v in row.items())
                + f"  (sender published at {res.send_rate:.0f} msg/s)",
                flush=True,
            )
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    med = {m: {k: statistics.median(v) for k, v in got[m].items()} for m in modes}
    print(
        f"\none-way latency over {lat_n} paced messages; throughput over {tput_n} messages "
        f"sent back to back, with the CPU time per message of the sending (tx) and receiving "
        f"(rx) process; median of {repeats} rounds"
    )
    print(f"{'mode':>12}  {'bytes':>5}  " + "  ".join(f"{h:>8}" for h, _ in COLUMNS.values()))
    for m in modes:
        cells = "  ".join(f.format(med[m][k]) for k, (_, f) in COLUMNS.items())
        print(f"{m:>12}  {sizes[m]:5d}  {cells}")
    best_lat = min(("raw-fifo", "raw-callback"), key=lambda m: med[m]["p50"])
    best_tput = max(("raw-fifo", "raw-callback"), key=lambda m: med[m]["rate"])
    lat_ratio = med["typed"]["p50"] / med[best_lat]["p50"]
    tput_ratio = med["typed"]["rate"] / med[best_tput]["rate"]
    print(f"\ntyped against the fastest raw pattern (latency: {best_lat}, rate: {best_tput}):")
    print(
        f"  latency p50 typed/raw = {lat_ratio:.2f}  (target <= 1.2)"
        f"  {'OK' if lat_ratio <= 1.2 else 'MISSED'}"
    )
    print(f"  latency p99 typed/raw = {med['typed']['p99'] / med[best_lat]['p99']:.2f}")
    print(
        f"  throughput typed/raw  = {tput_ratio:.2f}  (target >= 0.8)"
        f"  {'OK' if tput_ratio >= 0.8 else 'MISSED'}"
    )
    for side in ("send_cpu", "recv_cpu"):
        print(
            f"  {COLUMNS[side][0]} per message typed/raw = "
            f"{med['typed'][side] / med[best_tput][side]:.2f}"
        )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lat-n", type=int, default=3000, help="paced messages per latency run")
    ap.add_argument("--tput-n", type=int, default=50000, help="messages per throughput run")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median shown)")
    ap.add_argument("--diagnose", action="store_true", help="add the typed-pull and raw-queue rows")
    default_express = inspect.signature(Bus.publisher).parameters["express"].default
    ex = ap.add_mutually_exclusive_group()
    ex.add_argument(
        "--express",
        dest="express",
        action="store_true",
        default=default_express,
        help=f"express publishers, no batching (Bus.publisher's default: {default_express})",
    )
    ex.add_argument("--batched", dest="express", action="store_false", help="batching publishers")
    ap.add_argument(
        "--child",
        nargs=5,
        metavar=("MODE", "PHASE", "ENDPOINT", "RUN", "N"),
        help=argparse.SUPPRESS,
    )
    a = ap.parse_args()
    if a.child:
        mode, phase, endpoint, run, n = a.child
        sender(mode, phase, endpoint, run, int(n), a.express)
    else:
        main(a.lat_n, a.tput_n, a.repeats, a.diagnose, a.express)
