"""Benchmark the typed bus against raw zenoh-python + msgpack, across two processes on one machine.

Both paths run in the same invocation, peer to peer over tcp/127.0.0.1, with the same Zenoh
config (Bus/zenoh_config) and the same publisher options (RELIABLE, BLOCK, and express as
Bus.publisher's default unless --express/--batched says otherwise):

- typed-inbox: NavFix -> Publisher.put (encode)  ...  Inbox callback -> loop: Inbox.get (decode)
- typed-callback: NavFix -> Publisher.put  ...  Bus.subscribe_typed: decode in the Zenoh callback
- raw-queue: dict -> msgpack.packb -> put  ...  callback -> SimpleQueue -> loop: get, unpackb
- raw-callback: dict -> msgpack.packb -> put  ...  unpackb inside the Zenoh callback
- raw-fifo: dict -> msgpack.packb -> put  ...  FifoChannel -> loop: recv(), unpackb

Each typed pattern has a raw twin that hands the message over the same way (inbox <-> queue,
callback <-> callback); raw-fifo has no typed twin (the bus merges many subscriptions into
one inbox, which a per-subscription channel cannot). Ratios are printed per twin and for the
best typed pattern against the best raw one.

Latency is one-way: the sender stamps time.monotonic_ns() (CLOCK_MONOTONIC, system-wide on
Linux) into the payload before building it; the receiver reads the clock once the message is
decoded. Latency is measured in *pairs*: one sender and one receiver carry a typed pattern and
the raw pattern it is compared with at once, on two keys, and alternate message by message,
each paced by an acknowledgement. Whatever else the machine does then hits both sides alike,
so the ratio is steady even when the absolute numbers drift from run to run. Throughput: the
sender publishes as fast as it can, one pattern per run; the rate is
n / (last decoded - first stamped). Each process also reports its CPU time per message (all
its threads), which is far less sensitive to other load on the machine than the rates. Rounds
are repeated; medians are shown. The load average is printed: on a busy machine the rates and
latencies mean little.

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
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import msgpack
import zenoh

from common.bus import Bus, Inbox, Keys, Received
from common.config.bus import BusConfig
from common.messages import NavFix, encode
from common.runtime.procs import free_port

TWINS = {"typed-inbox": "raw-queue", "typed-callback": "raw-callback"}
MODES = (*TWINS, *TWINS.values(), "raw-fifo")
# Latency pairs, each measured in one run: every typed pattern with its twin, and the faster
# typed pattern (a callback: one thread switch, like raw-fifo's channel) with the raw fifo.
BEST_TYPED_LATENCY = "typed-callback"
PAIRS = (*TWINS.items(), (BEST_TYPED_LATENCY, "raw-fifo"), (BEST_TYPED_LATENCY, "raw-queue"))
# --diagnose adds typed-direct: an Inbox fed on Zenoh's network thread (Bus(low_latency=True)),
# which shows why that is not the default (the network thread then contends for the GIL).
DIAGNOSTIC = ("typed-direct",)
DIAGNOSTIC_PAIRS = (("typed-direct", "raw-queue"),)
INBOX_MODES = ("typed-inbox", "typed-direct")
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
    """The keys of one measurement: data per pattern, ack, the receiver's ready and done tokens."""

    keys: Keys

    def data(self, mode: str) -> str:
        # typed patterns publish through Bus.publisher("sender", "nav"); raw ones beside it
        return self.keys.stream("sender", "nav" if mode.startswith("typed") else "navraw")

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


def _putter(bus: Bus, ks: Keyset, mode: str, express: bool) -> Callable[[int], object]:
    """Build and publish message i, stamped with the send time, `mode`'s way."""
    if mode.startswith("typed"):
        pub = bus.publisher("sender", "nav", express=express)
        return lambda i: pub.put(navfix(time.monotonic_ns(), i))
    raw = _reliable_pub(bus.session, ks.data(mode), express)
    packb = msgpack.packb
    return lambda i: raw.put(packb(nav_dict(time.monotonic_ns(), i)))


def sender(modes: list[str], phase: str, endpoint: str, run: str, n: int, express: bool) -> None:
    """Publish n messages per mode, alternating between the modes; latency: each message after
    the previous one's ack. Then wait for done, so the session outlives the measurement."""
    ks = Keyset(Keys(run=run, vehicle="bench"))
    with Bus(BusConfig(connect=(endpoint,)), ks.keys) as bus:
        session = bus.session
        acks = session.declare_subscriber(ks.ack, zenoh.handlers.FifoChannel(16))
        try:
            _wait_token(session, ks.ready)  # declared after the receiver's subscribers
            puts = [_putter(bus, ks, mode, express) for mode in modes]
            cpu0 = time.process_time()  # every thread of this process, Zenoh's included
            for i in range(n):
                for put in puts:
                    put(i)
                    if phase == "latency":
                        acks.recv()
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


def _receive_with(
    bus: Bus, mode: str, key: str, rec: Recorder
) -> tuple[Callable[[], None] | None, Any]:
    """Subscribe `mode`'s way; returns the loop's pull-one step (None: a callback records)
    and the subscriber to undeclare (None: the bus owns it)."""
    session, now = bus.session, time.monotonic_ns
    if mode in INBOX_MODES:
        inbox = Inbox()
        bus.subscribe(key, inbox)

        def pull_inbox() -> None:
            ev = inbox.get(timeout=WAIT_S)
            t = now()
            if not isinstance(ev, Received):
                raise TimeoutError(f"{mode}: a message did not arrive ({ev!r})")
            rec.add(ev.msg.sent, t)

        return pull_inbox, None
    if mode == "typed-callback":
        bus.subscribe_typed(key, lambda r: rec.add(r.msg.sent, now()))
        return None, None
    unpackb = msgpack.unpackb
    if mode == "raw-callback":

        def on_sample(sample: zenoh.Sample) -> None:
            d = unpackb(sample.payload.to_bytes())
            rec.add(d["sent"], now())

        return None, session.declare_subscriber(key, on_sample)
    if mode == "raw-queue":
        handoff: queue.SimpleQueue[bytes] = queue.SimpleQueue()
        sub = session.declare_subscriber(key, lambda s: handoff.put(s.payload.to_bytes()))

        def pull_queue() -> None:
            d = unpackb(handoff.get(timeout=WAIT_S))
            rec.add(d["sent"], now())

        return pull_queue, sub
    assert mode == "raw-fifo", mode
    fifo = session.declare_subscriber(key, zenoh.handlers.FifoChannel(256))

    def pull_fifo() -> None:
        d = unpackb(fifo.recv().payload.to_bytes())
        rec.add(d["sent"], now())

    return pull_fifo, fifo


@dataclass(frozen=True)
class Result:
    """One mode's share of a measurement: one-way latencies (ns), rates, CPU per message."""

    latencies_ns: list[int]
    recv_rate: float
    send_rate: float
    send_cpu_us: float
    recv_cpu_us: float


def receive(modes: list[str], phase: str, n: int, express: bool) -> dict[str, Result]:
    """Run one measurement of one or more modes (interleaved) against a fresh sender."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    ks = Keyset(Keys(run=f"b{time.monotonic_ns()}", vehicle="bench"))
    low_latency = "typed-direct" in modes
    with Bus(BusConfig(listen=(endpoint,)), ks.keys, low_latency=low_latency) as bus:
        session = bus.session
        ack = _reliable_pub(session, ks.ack)
        recs = {m: Recorder(n, ack, paced=phase == "latency") for m in modes}
        pulls, subs = [], []
        for m in modes:
            pull, sub = _receive_with(bus, m, ks.data(m), recs[m])
            if pull is not None:
                pulls.append(pull)
            if sub is not None:
                subs.append(sub)
        token = session.liveliness().declare_token(ks.ready)
        cpu0 = time.process_time()
        child = subprocess.Popen(
            [sys.executable, __file__, "--child", ",".join(modes), phase, endpoint]
            + [ks.keys.run, str(n), "--express" if express else "--batched"],
            stdout=subprocess.PIPE,
            text=True,
        )
        try:
            # the sender alternates the modes message by message, paced or not; pulling each
            # pull-mode's next message in turn matches that order
            for _ in range(n):
                for pull in pulls:
                    pull()
            for m, rec in recs.items():
                if not rec.done.wait(WAIT_S * 3):
                    raise TimeoutError(f"{m}: {len(rec.recv)} of {n} arrived")
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
            for sub in subs:
                sub.undeclare()
            ack.undeclare()
    results = {}
    for m, rec in recs.items():
        lat = [r - s for s, r in zip(rec.sent, rec.recv, strict=True)]
        results[m] = Result(
            latencies_ns=lat[WARMUP:],
            recv_rate=n / ((rec.recv[-1] - rec.sent[0]) * 1e-9),
            send_rate=(n - 1) / (max(1, rec.sent[-1] - rec.sent[0]) * 1e-9),
            send_cpu_us=send_cpu_s / (n * len(modes)) * 1e6,
            recv_cpu_us=recv_cpu_s / (n * len(modes)) * 1e6,
        )
    return results


def _pct(xs: list[int], q: float) -> float:
    """q-quantile (0..1) in microseconds."""
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] / 1000.0


def _size(mode: str) -> int:
    if mode.startswith("typed"):
        return len(encode(navfix(0, 0)))
    return len(msgpack.packb(nav_dict(0, 0)))


def main(lat_n: int, tput_n: int, repeats: int, diagnose: bool, express: bool) -> None:
    """Repeat paired latency runs and per-mode throughput runs; print medians and ratios."""
    modes = MODES + DIAGNOSTIC if diagnose else MODES
    pairs = PAIRS + DIAGNOSTIC_PAIRS if diagnose else PAIRS
    lat: dict[tuple[str, str], dict[str, list[float]]] = {p: {} for p in pairs}
    tput: dict[str, dict[str, list[float]]] = {m: {} for m in modes}
    print(
        f"publishers (typed and raw alike): RELIABLE, BLOCK, express={express}; "
        f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs",
        flush=True,
    )
    for r in range(repeats):
        for pair in pairs:
            got = receive(list(pair), "latency", lat_n + WARMUP, express)
            for m in pair:
                for q, name in ((0.5, "p50"), (0.99, "p99")):
                    lat[pair].setdefault(f"{m} {name}", []).append(_pct(got[m].latencies_ns, q))
            print(
                f"round {r + 1}/{repeats} latency "
                + "  ".join(f"{m} p50 {_pct(got[m].latencies_ns, 0.5):.1f} us" for m in pair),
                flush=True,
            )
        for mode in modes:
            res = receive([mode], "throughput", tput_n, express)[mode]
            for k, v in (
                ("rate", res.recv_rate),
                ("tx", res.send_cpu_us),
                ("rx", res.recv_cpu_us),
            ):
                tput[mode].setdefault(k, []).append(v)
            print(
                f"round {r + 1}/{repeats} throughput {mode:>14}: {res.recv_rate:8.0f} msg/s  "
                f"tx cpu {res.send_cpu_us:.2f} us  rx cpu {res.recv_cpu_us:.2f} us  "
                f"(sender published at {res.send_rate:.0f} msg/s)",
                flush=True,
            )
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    med = statistics.median
    print(
        f"\nthroughput over {tput_n} messages sent back to back, with the CPU time per message "
        f"of the sending (tx) and receiving (rx) process; median of {repeats} rounds"
    )
    print(f"{'mode':>14}  {'bytes':>5}  {'msg/s':>8}  {'tx cpu us':>9}  {'rx cpu us':>9}")
    for m in modes:
        t = tput[m]
        print(
            f"{m:>14}  {_size(m):5d}  {med(t['rate']):8.0f}  {med(t['tx']):9.2f}"
            f"  {med(t['rx']):9.2f}"
        )
    print(
        f"\none-way latency over {lat_n} paced messages per pattern, the two patterns of a pair "
        f"alternating in one run; median of {repeats} rounds"
    )
    lat_ratio: dict[tuple[str, str], float] = {}
    for pair in pairs:
        typed, raw = pair
        L = {k: med(v) for k, v in lat[pair].items()}
        lat_ratio[pair] = L[f"{typed} p50"] / L[f"{raw} p50"]
        print(
            f"  {typed:>14} p50 {L[f'{typed} p50']:6.1f} p99 {L[f'{typed} p99']:6.1f} us   "
            f"{raw:>12} p50 {L[f'{raw} p50']:6.1f} p99 {L[f'{raw} p99']:6.1f} us   "
            f"typed/raw p50 {lat_ratio[pair]:.2f}  p99 {L[f'{typed} p99'] / L[f'{raw} p99']:.2f}"
        )
    print("\neach typed pattern against its raw twin (the same handover):")
    for typed, raw in TWINS.items():
        print(
            f"  {typed:>14} / {raw:<12}  latency p50 {lat_ratio[(typed, raw)]:.2f}"
            f"  throughput {med(tput[typed]['rate']) / med(tput[raw]['rate']):.2f}"
            f"  tx cpu {med(tput[typed]['tx']) / med(tput[raw]['tx']):.2f}"
            f"  rx cpu {med(tput[typed]['rx']) / med(tput[raw]['rx']):.2f}"
        )
    raws = [m for m in MODES if m.startswith("raw")]
    rate_t = max(TWINS, key=lambda m: med(tput[m]["rate"]))
    rate_r = max(raws, key=lambda m: med(tput[m]["rate"]))
    tput_ratio = med(tput[rate_t]["rate"]) / med(tput[rate_r]["rate"])
    # the fastest typed pattern against each raw one, paired; the worst of those ratios is
    # the one that counts (it is against the fastest raw pattern)
    best_pairs = [p for p in PAIRS if p[0] == BEST_TYPED_LATENCY]
    worst = max(best_pairs, key=lambda p: lat_ratio[p])
    print("\nthe best typed pattern against the best raw one:")
    print(
        f"  latency p50 {worst[0]}/{worst[1]} = {lat_ratio[worst]:.2f}  (target <= 1.2)"
        f"  {'OK' if lat_ratio[worst] <= 1.2 else 'MISSED'}"
        f"  (against every raw pattern: "
        + ", ".join(f"{p[1]} {lat_ratio[p]:.2f}" for p in best_pairs)
        + ")"
    )
    print(
        f"  throughput {rate_t}/{rate_r} = {tput_ratio:.2f}  (target >= 0.8)"
        f"  {'OK' if tput_ratio >= 0.8 else 'MISSED'}"
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lat-n", type=int, default=3000, help="paced messages per latency run")
    ap.add_argument("--tput-n", type=int, default=50000, help="messages per throughput run")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median shown)")
    ap.add_argument("--diagnose", action="store_true", help="add the typed-direct row")
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
        metavar=("MODES", "PHASE", "ENDPOINT", "RUN", "N"),
        help=argparse.SUPPRESS,
    )
    a = ap.parse_args()
    if a.child:
        modes, phase, endpoint, run, n = a.child
        sender(modes.split(","), phase, endpoint, run, int(n), a.express)
    else:
        main(a.lat_n, a.tput_n, a.repeats, a.diagnose, a.express)
