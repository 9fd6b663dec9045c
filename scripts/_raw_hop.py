"""Raw zenoh-python latency between two processes (baselines for the runtime benchmark).

    _raw_hop.py N        one-way hop, peer to peer, one sample a millisecond: prints
                         "p50_us p99_us"
    _raw_hop.py N MS [router] [fast]
                         the same, one sample every MS milliseconds (a loop's pace: between
                         samples each process sleeps, and pays its wake-up on the next);
                         with `router`, from a client through a router to a client, as a
                         service's message goes: three processes, the router one of its own
                         (as `tidelink router`), this one the subscriber; with `fast`, over
                         the quickest transport
                         Zenoh has here, not the one tidelink uses: a Unix socket instead
                         of TCP on loopback, and Zenoh's lowlatency transport (no transmit
                         queue or task: the putting thread writes the socket; no QoS)
    _raw_hop.py rtt N [K]
                         round trip through a router, the shape of a lockstep tick: this
                         process is a router (as the lockstep coordinator is), each of K
                         children (1 unless given) a client that answers every ping; a round
                         ends when all K answers are in (K > 1: a tick's fan-out to its due
                         services, with no work in them); prints "p50_us p99_us"

The child publishes CLOCK_MONOTONIC stamps (system-wide on Linux).
"""

from __future__ import annotations

import json
import os
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time

import numpy as np
import zenoh


def _conf(
    listen: str | None, connect: str | None, mode: str = "peer", fast: bool = False
) -> zenoh.Config:
    c = zenoh.Config()
    c.insert_json5("mode", json.dumps(mode))
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("scouting/delay", "0")
    c.insert_json5("listen/endpoints", json.dumps([listen] if listen else []))
    c.insert_json5("connect/endpoints", json.dumps([connect] if connect else []))
    if fast:  # both ends of a link must agree on it
        c.insert_json5("transport/unicast/lowlatency", "true")
        c.insert_json5("transport/unicast/qos/enabled", "false")
    return c


def _endpoint(fast: bool = False) -> str:
    if fast:  # a socket file of its own (Zenoh removes it on close)
        return f"unixsock-stream/{tempfile.gettempdir()}/tidelink-raw-hop-{os.getpid()}.sock"
    with socket.socket() as so:
        so.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{so.getsockname()[1]}"


def child(endpoint: str, n: int, interval_s: float, mode: str, fast: bool) -> None:
    with zenoh.open(_conf(None, endpoint, mode, fast)) as s:
        pub = s.declare_publisher("bench/hop", reliability=zenoh.Reliability.RELIABLE)
        time.sleep(0.5)  # benchmark warm-up: let the subscription propagate (not a test)
        for _ in range(n):
            pub.put(struct.pack("<q", time.monotonic_ns()))
            time.sleep(interval_s)
        pub.put(b"")


def parent(n: int, interval_s: float = 0.001, via_router: bool = False, fast: bool = False) -> None:
    endpoint = _endpoint(fast)
    mode = "client" if via_router else "peer"
    lat: list[int] = []
    done = threading.Event()

    def on(sample: zenoh.Sample) -> None:
        now = time.monotonic_ns()
        b = sample.payload.to_bytes()
        if not b:
            done.set()
            return
        lat.append(now - struct.unpack("<q", b)[0])

    router = None
    if via_router:
        router = subprocess.Popen(
            [sys.executable, __file__, "router", endpoint, "fast" if fast else "tcp"],
            stdout=subprocess.PIPE,
            text=True,
        )
        assert router.stdout is not None
        router.stdout.readline()  # "listening"
    with zenoh.open(
        _conf(None, endpoint, mode, fast) if via_router else _conf(endpoint, None, fast=fast)
    ) as s:
        sub = s.declare_subscriber("bench/hop", on)
        args = ["child", endpoint, str(n), str(interval_s), mode, "fast" if fast else "tcp"]
        proc = subprocess.Popen([sys.executable, __file__, *args])
        done.wait(timeout=60 + 2 * n * interval_s)
        proc.wait(timeout=10)
        sub.undeclare()
    if router is not None:
        router.terminate()
        router.wait(timeout=10)
    a = np.array(lat[n // 20 :]) / 1e3  # the first samples warm up
    print(f"{np.percentile(a, 50):.1f} {np.percentile(a, 99):.1f}")


def rtt_child(endpoint: str, name: str) -> None:
    """Answer every ping with a pong, in a Python callback handed to a loop (as a service)."""
    with zenoh.open(_conf(None, endpoint, "client")) as s:
        pong = s.declare_publisher("bench/pong", reliability=zenoh.Reliability.RELIABLE)
        pings = s.declare_subscriber("bench/ping", zenoh.handlers.FifoChannel(16))
        token = s.liveliness().declare_token(f"bench/ready/{name}")
        for sample in pings:
            b = sample.payload.to_bytes()
            pong.put(b)
            if not b:
                break
        token.undeclare()
        pings.undeclare()


def rtt_parent(n: int, k: int = 1) -> None:
    endpoint = _endpoint()
    with zenoh.open(_conf(endpoint, None, "router")) as s:
        up: set[str] = set()
        ready = threading.Event()

        def on_ready(smp: zenoh.Sample) -> None:
            up.add(str(smp.key_expr))
            if len(up) == k:
                ready.set()

        live = s.liveliness().declare_subscriber("bench/ready/*", on_ready, history=True)
        pongs = s.declare_subscriber("bench/pong", zenoh.handlers.FifoChannel(16 * k))
        ping = s.declare_publisher("bench/ping", reliability=zenoh.Reliability.RELIABLE)
        procs = [
            subprocess.Popen([sys.executable, __file__, "rtt-child", endpoint, str(i)])
            for i in range(k)
        ]
        if not ready.wait(30):
            raise TimeoutError(f"{k - len(up)} of the {k} pong processes did not come up")
        rtts = []
        for _ in range(n):
            t0 = time.monotonic_ns()
            ping.put(b"p")
            for _ in range(k):
                pongs.recv()
            rtts.append(time.monotonic_ns() - t0)
        ping.put(b"")
        for proc in procs:
            proc.wait(timeout=10)
        live.undeclare()
        pongs.undeclare()
    a = np.array(rtts[100:]) / 1e3
    print(f"{np.percentile(a, 50):.1f} {np.percentile(a, 99):.1f}")


def router_process(endpoint: str, fast: bool) -> None:
    """A router and nothing else, until terminated."""
    with zenoh.open(_conf(endpoint, None, "router", fast)):
        print("listening", flush=True)
        try:
            threading.Event().wait()
        except KeyboardInterrupt:
            pass


if __name__ == "__main__":
    if sys.argv[1] == "router":
        signal.signal(signal.SIGTERM, lambda *_: sys.exit(0))
        router_process(sys.argv[2], sys.argv[3] == "fast")
    elif sys.argv[1] == "child":
        child(sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), sys.argv[5], sys.argv[6] == "fast")
    elif sys.argv[1] == "rtt-child":
        rtt_child(sys.argv[2], sys.argv[3])
    elif sys.argv[1] == "rtt":
        rtt_parent(int(sys.argv[2]), int(sys.argv[3]) if len(sys.argv) > 3 else 1)
    else:
        ms = float(sys.argv[2]) if len(sys.argv) > 2 else 1.0
        flags = sys.argv[3:]
        parent(int(sys.argv[1]), ms / 1e3, "router" in flags, "fast" in flags)
