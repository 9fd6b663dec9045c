"""One hop of the realtime loop through its router, plain / mTLS / mTLS + ACL (a baseline for
the runtime benchmark).

    _bus_hop.py VARIANT N [CERTS]    VARIANT: plain | mtls | mtls+acl

This process is the router, as a `tidelink run` process is (mode router, the launcher
identity; with mtls+acl it enforces the access control generated from the test loop's
dataflow). Two clients over the typed bus, as the loop's services: "sensor" publishes NavFix
on its nav stream (RELIABLE, BLOCK, not express, as services publish), one every 1 ms,
stamped with CLOCK_MONOTONIC (system-wide on Linux); "filter" takes them from an Inbox fed on
Zenoh's thread (low_latency, as services do) until it has N. The sender starts once the
router's clock token appears (declared when the receiver's is there) and stops when it
goes, as a service does: only what the ACL grants the two identities is used.

Prints "p50_us p99_us open_rx_ms open_tx_ms": the one-way latency after WARMUP messages,
and how long each client took to open its session (connecting, and the TLS handshake).
"""

from __future__ import annotations

import subprocess
import sys
import threading
import time

import numpy as np

# the payload bench_bus measures (run as a script: scripts/ is on the path)
from bench_bus import navfix

from common.bus import CLOCK, Bus, Inbox, Keys, Liveliness, Received
from common.config.bus import BusConfig
from common.runtime.distributed.acl import LAUNCHER, access_control, run_grants
from common.runtime.processes.children import free_port
from tests.helpers.testloop import TestLoopParams, testloop_dataflow

VARIANTS = ("plain", "mtls", "mtls+acl")
KEYS = Keys("hop", "bench")
SENDER, RECEIVER = "sensor", "filter"  # the loop's first hop; their certificates and grants
WARMUP = 200
WAIT_S = 30.0


def _base(certs: str) -> BusConfig:
    """Plain, or mutual TLS with the certificates in `certs` (tcp/ endpoints served as tls/)."""
    return BusConfig(security="mtls", certs=certs) if certs else BusConfig()


def sender(endpoint: str, certs: str) -> None:
    """Publish stamped NavFixes every 1 ms while the router's clock token exists."""
    cfg = _base(certs).client_of(endpoint)
    t0 = time.perf_counter()
    with Bus(cfg, KEYS, identity=SENDER) as bus:
        open_ms = (time.perf_counter() - t0) * 1e3
        started, gone = threading.Event(), threading.Event()

        def on_clock(ev: Liveliness) -> None:
            (started if ev.alive else gone).set()

        bus.on_alive(KEYS.alive(CLOCK), on_clock)
        pub = bus.publisher(SENDER, "nav")
        if not started.wait(WAIT_S):
            raise TimeoutError("no clock token")
        seq = 0
        while not gone.is_set():
            pub.put(navfix(time.monotonic_ns(), seq))
            seq += 1
            time.sleep(0.001)  # pacing: one message a millisecond, as the loop's sensor
    print(f"{open_ms:.1f}")


def receiver(endpoint: str, certs: str, n: int) -> None:
    """Take n NavFixes; print the one-way latency after WARMUP and the session's open time."""
    cfg = _base(certs).client_of(endpoint)
    t0 = time.perf_counter()
    with Bus(cfg, KEYS, low_latency=True, identity=RECEIVER) as bus:
        open_ms = (time.perf_counter() - t0) * 1e3
        inbox = Inbox()
        bus.subscribe(KEYS.stream(SENDER, "nav"), inbox)
        bus.declare_alive(RECEIVER)
        lat: list[int] = []
        while len(lat) < n + WARMUP:
            ev = inbox.get(timeout=WAIT_S)
            now = time.monotonic_ns()
            if not isinstance(ev, Received):
                raise TimeoutError(f"a message did not arrive ({ev!r})")
            lat.append(now - round(ev.msg.sent * 1e9))
    us = np.array(lat[WARMUP:]) / 1e3
    print(f"{np.percentile(us, 50):.1f} {np.percentile(us, 99):.1f} {open_ms:.1f}")


def router(variant: str, n: int, certs: str) -> None:
    """Route one measurement between a fresh receiver and sender; print its results."""
    if variant not in VARIANTS or (variant != "plain") != bool(certs):
        raise SystemExit(f"usage: _bus_hop.py {'|'.join(VARIANTS)} N [CERTS] (certs for mtls)")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    acl = None
    if variant == "mtls+acl":
        acl = access_control(run_grants(testloop_dataflow(TestLoopParams()), KEYS))
    cfg = _base(certs).router_on((endpoint,))
    with Bus(cfg, KEYS, identity=LAUNCHER, access_control=acl) as bus:
        ready = threading.Event()
        bus.on_alive(KEYS.alive(RECEIVER), lambda ev: ready.set() if ev.alive else None)
        me = [sys.executable, __file__]
        rx = subprocess.Popen([*me, "rx", endpoint, certs, str(n)], stdout=subprocess.PIPE)
        tx = subprocess.Popen([*me, "tx", endpoint, certs], stdout=subprocess.PIPE)
        try:
            if not ready.wait(WAIT_S):
                raise TimeoutError("the receiver did not come up")
            clock = bus.session.liveliness().declare_token(KEYS.alive(CLOCK))
            out_rx, _ = rx.communicate(timeout=WAIT_S * 2)
            clock.undeclare()  # the sender stops
            out_tx, _ = tx.communicate(timeout=WAIT_S)
        finally:
            for p in (rx, tx):
                if p.poll() is None:
                    p.kill()
                    p.wait()
    if rx.returncode or tx.returncode:
        raise RuntimeError(f"{variant}: receiver exited {rx.returncode}, sender {tx.returncode}")
    print(out_rx.decode().strip(), out_tx.decode().strip())


if __name__ == "__main__":
    role, args = sys.argv[1], sys.argv[2:]
    if role == "tx":
        sender(args[0], args[1])
    elif role == "rx":
        receiver(args[0], args[1], int(args[2]))
    else:
        router(role, int(args[0]), args[1] if len(args) > 1 else "")
