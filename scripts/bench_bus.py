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

Every comparison is measured in *pairs*: one sender and one receiver carry a typed pattern
and the raw pattern it is compared with at once, on two keys, taking turns; whatever else the
machine does then hits both alike, so the ratios hold steady while absolute numbers drift
from run to run (they did, by +-30 %, when each pattern ran on its own). Latency is one-way:
the sender stamps time.monotonic_ns() (CLOCK_MONOTONIC, system-wide on Linux) into the
payload before building it, the receiver reads the clock once the message is decoded; the
patterns alternate message by message, each message paced by an acknowledgement.
Throughput: the patterns alternate in turns of many messages sent back to back, each turn
acknowledged before the next; a turn's rate is its messages / (last decoded - first
stamped). Rounds are repeated; medians are shown. The load average is printed: on a busy
machine the rates and latencies mean little.

Mutual TLS (the secured bus, docs/security.md): each round also runs the typed-inbox /
raw-queue pair over tls/ with certificates of a CA made for this run (common/bus/certs.py,
in a temporary directory), right after the same pair over tcp/, and tls/tcp ratios are
printed per pattern. The two sessions are peers, so there is no router and no access
control in these rows (scripts/bench_runtime.py measures a run whose router enforces one).
--no-tls skips them.

    .venv/bin/python scripts/bench_bus.py [--lat-n 3000] [--tput-n 50000] [--repeats 3]
        [--turns 5] [--express | --batched] [--diagnose] [--no-tls]
"""

from __future__ import annotations

import argparse
import inspect
import os
import queue
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import msgpack
import zenoh

from common.bus import Bus, Inbox, Keys, Received
from common.bus.certs import create_certs
from common.config.bus import BusConfig
from common.messages import NavFix, encode
from common.runtime.processes.children import free_port

TWINS = {"typed-inbox": "raw-queue", "typed-callback": "raw-callback"}
RAWS = ("raw-queue", "raw-callback", "raw-fifo")
# Every typed pattern against every raw one, each pair measured in one run (see above).
PAIRS = tuple((t, w) for t in TWINS for w in RAWS)
# --diagnose adds typed-direct: an Inbox fed on Zenoh's network thread (Bus(low_latency=True)),
# which shows why that is not the default (the network thread then contends for the GIL).
DIAGNOSTIC_PAIRS = (("typed-direct", "raw-queue"),)
INBOX_MODES = ("typed-inbox", "typed-direct")
# the pair also measured over tls/ (mutual TLS) each round, against its tcp/ run of the round
TLS_PAIR = ("typed-inbox", "raw-queue")
SENDER, RECEIVER = "sender", "receiver"  # the identities (certificate CNs) of the two processes
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


def bus_config(certs: str, *, listen: str = "", connect: str = "") -> BusConfig:
    """A peer on one endpoint; under mutual TLS when `certs` names a certificates directory
    (the tcp/ endpoint is then served as tls/ on the same address, BusConfig.endpoint)."""
    return BusConfig(
        listen=(listen,) if listen else (),
        connect=(connect,) if connect else (),
        security="mtls" if certs else "none",
        certs=certs,
    )


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


def sender(
    modes: list[str],
    phase: str,
    endpoint: str,
    run: str,
    n: int,
    unit: int,
    express: bool,
    certs: str = "",
    identity: str = SENDER,
) -> None:
    """Publish n messages per mode in turns of `unit` messages per mode. Latency (unit 1):
    each message after the previous one's ack; throughput: each turn back to back, the next
    turn after the receiver acknowledged this one. Then wait for done, so the session
    outlives the measurement. With `certs`: over mutual TLS, presenting `identity`."""
    ks = Keyset(Keys(run=run, vehicle="bench"))
    with Bus(bus_config(certs, connect=endpoint), ks.keys, identity=identity) as bus:
        session = bus.session
        acks = session.declare_subscriber(ks.ack, zenoh.handlers.FifoChannel(16))
        try:
            _wait_token(session, ks.ready)  # declared after the receiver's subscribers
            puts = [_putter(bus, ks, mode, express) for mode in modes]
            for turn in range(n // unit):
                for put in puts:
                    for i in range(turn * unit, (turn + 1) * unit):
                        put(i)
                        if phase == "latency":
                            acks.recv()
                    if phase != "latency":
                        acks.recv()
            _wait_token(session, ks.done)  # keep the session until everything is consumed
        finally:
            acks.undeclare()


# --- the receiver (this process) ---------------------------------------------------------------


class Recorder:
    """Per-message bookkeeping, identical in every mode: stamps in, an ack out after every
    `every` messages (1: pacing for latency; a turn's length for throughput)."""

    def __init__(self, n: int, ack: Any, every: int) -> None:
        self.n, self.ack, self.every = n, ack, every
        self.sent: list[int] = []
        self.recv: list[int] = []
        self.done = threading.Event()

    def add(self, sent_s: float, recv_ns: int) -> None:
        self.sent.append(round(sent_s * 1e9))
        self.recv.append(recv_ns)
        if len(self.recv) % self.every == 0:
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
    """One mode's share of a measurement: one-way latencies (ns), receive rate per turn."""

    latencies_ns: list[int]
    turn_rates: list[float]  # msg/s of each turn: its messages / (last received - first sent)


def receive(
    modes: list[str], phase: str, n: int, unit: int, express: bool, certs: str = ""
) -> dict[str, Result]:
    """One measurement of the modes, taking turns of `unit` messages, against a fresh sender;
    over mutual TLS when `certs` names a directory holding the sender's and receiver's
    certificates (tcp/ otherwise)."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    ks = Keyset(Keys(run=f"b{time.monotonic_ns()}", vehicle="bench"))
    low_latency = "typed-direct" in modes
    cfg = bus_config(certs, listen=endpoint)
    with Bus(cfg, ks.keys, low_latency=low_latency, identity=RECEIVER) as bus:
        session = bus.session
        ack = _reliable_pub(session, ks.ack)
        recs = {m: Recorder(n, ack, 1 if phase == "latency" else unit) for m in modes}
        pulls, subs = [], []
        for m in modes:
            pull, sub = _receive_with(bus, m, ks.data(m), recs[m])
            if pull is not None:
                pulls.append(pull)
            if sub is not None:
                subs.append(sub)
        token = session.liveliness().declare_token(ks.ready)
        child = subprocess.Popen(
            [sys.executable, __file__, "--child", ",".join(modes), phase, endpoint]
            + [ks.keys.run, str(n), str(unit), "--express" if express else "--batched"]
            + (["--certs", certs, "--identity", SENDER] if certs else []),
        )
        try:
            # the sender takes the modes in turns of `unit` messages; pulling each pull-mode's
            # turn in the same order matches it (callback modes record on their own)
            for _ in range(n // unit):
                for pull in pulls:
                    for _ in range(unit):
                        pull()
            for m, rec in recs.items():
                if not rec.done.wait(WAIT_S * 3):
                    raise TimeoutError(f"{m}: {len(rec.recv)} of {n} arrived")
            done_token = session.liveliness().declare_token(ks.done)
            child.wait(timeout=WAIT_S)
            if child.returncode != 0:
                raise RuntimeError(f"sender exited with {child.returncode}")
            done_token.undeclare()
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
        rates = [unit / ((rec.recv[i + unit - 1] - rec.sent[i]) * 1e-9) for i in range(0, n, unit)]
        results[m] = Result(latencies_ns=lat[WARMUP:], turn_rates=rates)
    return results


def _pct(xs: list[int], q: float) -> float:
    """q-quantile (0..1) in microseconds."""
    s = sorted(xs)
    return s[min(len(s) - 1, int(q * len(s)))] / 1000.0


def _size(mode: str) -> int:
    if mode.startswith("typed"):
        return len(encode(navfix(0, 0)))
    return len(msgpack.packb(nav_dict(0, 0)))


Samples = dict[str, list[float]]  # "p50"/"p99" + mode -> one value per round; mode -> rates


def measure_pair(
    pair: tuple[str, str],
    lat_n: int,
    unit: int,
    turns: int,
    express: bool,
    certs: str,
    lat: Samples,
    rate: Samples,
    label: str,
) -> None:
    """One paired latency run and one paired throughput run of `pair` (over mutual TLS when
    `certs` is set), added to `lat` and `rate`; prints the round's line after `label`."""
    got = receive(list(pair), "latency", lat_n + WARMUP, 1, express, certs)
    tp = receive(list(pair), "throughput", unit * turns, unit, express, certs)
    for m in pair:
        for q, name in ((0.5, "p50"), (0.99, "p99")):
            lat.setdefault(name + m, []).append(_pct(got[m].latencies_ns, q))
        rate.setdefault(m, []).extend(tp[m].turn_rates)
    print(
        label
        + "  ".join(
            f"{m} p50 {_pct(got[m].latencies_ns, 0.5):.1f} us, "
            f"{statistics.median(tp[m].turn_rates):.0f} msg/s"
            for m in pair
        ),
        flush=True,
    )


def main(
    lat_n: int, tput_n: int, turns: int, repeats: int, diagnose: bool, express: bool, tls: bool
) -> None:
    """Repeat paired latency and paired throughput runs; print medians and ratios. With `tls`,
    the TLS_PAIR also over mutual TLS each round, with certificates made for this run."""
    pairs = PAIRS + DIAGNOSTIC_PAIRS if diagnose else PAIRS
    unit = max(1, tput_n // turns)
    lat: dict[tuple[str, str], Samples] = {p: {} for p in pairs}
    rate: dict[tuple[str, str], Samples] = {p: {} for p in pairs}
    tls_lat: Samples = {}
    tls_rate: Samples = {}
    print(
        f"publishers (typed and raw alike): RELIABLE, BLOCK, express={express}; "
        f"load average before: {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs",
        flush=True,
    )
    with tempfile.TemporaryDirectory(prefix="tidelink-bench-certs-") as certs:
        if tls:
            create_certs(Path(certs), [SENDER, RECEIVER])
        for r in range(repeats):
            for pair in pairs:
                label = f"round {r + 1}/{repeats} "
                measure_pair(pair, lat_n, unit, turns, express, "", lat[pair], rate[pair], label)
                if tls and pair == TLS_PAIR:  # right after its tcp/ run: the same conditions
                    label = f"round {r + 1}/{repeats} over tls/ "
                    measure_pair(pair, lat_n, unit, turns, express, certs, tls_lat, tls_rate, label)
    print(f"load average after: {os.getloadavg()[0]:.2f}")
    med = statistics.median
    print(
        f"\nEach pair ran in one sender/receiver pair: latency over {lat_n} paced messages per "
        f"pattern, alternating message by message (median of {repeats} rounds); throughput "
        f"in turns of {unit} messages sent back to back, alternating turn by turn (median over "
        f"{turns * repeats} turns). Payload: typed {_size('typed')} bytes, raw {_size('raw')}."
    )
    print(f"{'typed':>14} {'raw':>12}  {'p50 us':>13}  {'p99 us':>13}  {'msg/s':>15}  ratios")
    lat_ratio: dict[tuple[str, str], float] = {}
    tput_ratio: dict[tuple[str, str], float] = {}
    for pair in pairs:
        t, w = pair
        L = {k: med(v) for k, v in lat[pair].items()}
        R = {k: med(v) for k, v in rate[pair].items()}
        lat_ratio[pair] = L["p50" + t] / L["p50" + w]
        tput_ratio[pair] = R[t] / R[w]
        print(
            f"{t:>14} {w:>12}  {L['p50' + t]:6.1f} {L['p50' + w]:6.1f}  "
            f"{L['p99' + t]:6.1f} {L['p99' + w]:6.1f}  {R[t]:7.0f} {R[w]:7.0f}  "
            f"latency p50 {lat_ratio[pair]:.2f}, p99 {L['p99' + t] / L['p99' + w]:.2f}; "
            f"throughput {tput_ratio[pair]:.2f}"
        )
    print("\neach typed pattern against its raw twin (the same handover):")
    for t, w in TWINS.items():
        print(
            f"  {t:>14} / {w:<12}  latency p50 {lat_ratio[(t, w)]:.2f}"
            f"  throughput {tput_ratio[(t, w)]:.2f}"
        )
    # The verdict: the best typed pattern against *every* raw pattern (so against the
    # fastest raw one), each ratio from a paired run.
    best_lat = min(TWINS, key=lambda t: max(lat_ratio[(t, w)] for w in RAWS))
    worst_lat = max(RAWS, key=lambda w: lat_ratio[(best_lat, w)])
    best_tp = max(TWINS, key=lambda t: min(tput_ratio[(t, w)] for w in RAWS))
    worst_tp = min(RAWS, key=lambda w: tput_ratio[(best_tp, w)])
    lr, tr = lat_ratio[(best_lat, worst_lat)], tput_ratio[(best_tp, worst_tp)]
    print("\nthe best typed pattern against every raw pattern (the worst ratio shown):")
    print(
        f"  latency p50 {best_lat}/{worst_lat} = {lr:.2f}  (target <= 1.2)"
        f"  {'OK' if lr <= 1.2 else 'MISSED'}"
    )
    print(
        f"  throughput {best_tp}/{worst_tp} = {tr:.2f}  (target >= 0.8)"
        f"  {'OK' if tr >= 0.8 else 'MISSED'}"
    )
    if tls:
        report_tls(lat[TLS_PAIR], rate[TLS_PAIR], tls_lat, tls_rate, repeats)


def report_tls(
    tcp_lat: Samples, tcp_rate: Samples, tls_lat: Samples, tls_rate: Samples, repeats: int
) -> None:
    """TLS_PAIR over tls/ against the same pair over tcp/: medians and tls/tcp ratios."""
    med = statistics.median
    print(
        f"\nmutual TLS against plain tcp/: the {' / '.join(TLS_PAIR)} pair over tls/ (both "
        "peers present a certificate of a CA made for this run), each round right after the "
        f"same pair over tcp/ (median of {repeats} rounds). Peer to peer: no router, so no "
        "access control in these rows (scripts/bench runtime measures a secured run, whose "
        "router enforces one)."
    )
    print(f"{'pattern':>14}  {'p50 us':>13}  {'p99 us':>13}  {'msg/s':>15}  tls/tcp")
    print(f"{'':>14}  {'tcp':>6} {'tls':>6}  {'tcp':>6} {'tls':>6}  {'tcp':>7} {'tls':>7}")
    for m in TLS_PAIR:
        p50 = med(tcp_lat["p50" + m]), med(tls_lat["p50" + m])
        p99 = med(tcp_lat["p99" + m]), med(tls_lat["p99" + m])
        tput = med(tcp_rate[m]), med(tls_rate[m])
        rounds = [b / a for a, b in zip(tcp_lat["p50" + m], tls_lat["p50" + m], strict=True)]
        print(
            f"{m:>14}  {p50[0]:6.1f} {p50[1]:6.1f}  {p99[0]:6.1f} {p99[1]:6.1f}  "
            f"{tput[0]:7.0f} {tput[1]:7.0f}  latency p50 {p50[1] / p50[0]:.2f} "
            f"(rounds {min(rounds):.2f}-{max(rounds):.2f}), p99 {p99[1] / p99[0]:.2f}; "
            f"throughput {tput[1] / tput[0]:.2f}"
        )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--lat-n", type=int, default=3000, help="paced messages per latency run")
    ap.add_argument(
        "--tput-n", type=int, default=50000, help="messages per pattern per throughput run"
    )
    ap.add_argument("--turns", type=int, default=5, help="turns per pattern per throughput run")
    ap.add_argument("--repeats", type=int, default=3, help="interleaved rounds (median shown)")
    ap.add_argument("--diagnose", action="store_true", help="add the typed-direct row")
    ap.add_argument(
        "--no-tls",
        dest="tls",
        action="store_false",
        help="skip the rows over mutual TLS (tls/ against tcp/)",
    )
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
        nargs=6,
        metavar=("MODES", "PHASE", "ENDPOINT", "RUN", "N", "UNIT"),
        help=argparse.SUPPRESS,
    )
    # the child's side of mutual TLS: the run's certificates directory and whose to present
    ap.add_argument("--certs", default="", help=argparse.SUPPRESS)
    ap.add_argument("--identity", default=SENDER, help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        modes, phase, endpoint, run, n, unit = a.child
        sender(
            modes.split(","),
            phase,
            endpoint,
            run,
            int(n),
            int(unit),
            a.express,
            certs=a.certs,
            identity=a.identity,
        )
    else:
        main(a.lat_n, a.tput_n, a.turns, a.repeats, a.diagnose, a.express, a.tls)
