"""Raw zenoh-python one-way hop latency between two processes (baseline for the benchmarks).

Prints "p50_us p99_us". The child publishes CLOCK_MONOTONIC stamps (system-wide on Linux).
"""

from __future__ import annotations

import json
import socket
import struct
import subprocess
import sys
import threading
import time

import numpy as np
import zenoh


def _conf(listen: str | None, connect: str | None) -> zenoh.Config:
    c = zenoh.Config()
    c.insert_json5("scouting/multicast/enabled", "false")
    c.insert_json5("listen/endpoints", json.dumps([listen] if listen else []))
    c.insert_json5("connect/endpoints", json.dumps([connect] if connect else []))
    return c


def child(endpoint: str, n: int) -> None:
    with zenoh.open(_conf(None, endpoint)) as s:
        pub = s.declare_publisher("bench/hop", reliability=zenoh.Reliability.RELIABLE)
        time.sleep(0.5)  # benchmark warm-up: let the subscription propagate (not a test)
        for _ in range(n):
            pub.put(struct.pack("<q", time.monotonic_ns()))
            time.sleep(0.001)
        pub.put(b"")


def parent(n: int) -> None:
    with socket.socket() as so:
        so.bind(("127.0.0.1", 0))
        port = so.getsockname()[1]
    endpoint = f"tcp/127.0.0.1:{port}"
    lat: list[int] = []
    done = threading.Event()

    def on(sample: zenoh.Sample) -> None:
        now = time.monotonic_ns()
        b = sample.payload.to_bytes()
        if not b:
            done.set()
            return
        lat.append(now - struct.unpack("<q", b)[0])

    with zenoh.open(_conf(endpoint, None)) as s:
        sub = s.declare_subscriber("bench/hop", on)
        proc = subprocess.Popen([sys.executable, __file__, "child", endpoint, str(n)])
        done.wait(timeout=60)
        proc.wait(timeout=10)
        sub.undeclare()
    a = np.array(lat[100:]) / 1e3
    print(f"{np.percentile(a, 50):.1f} {np.percentile(a, 99):.1f}")


if __name__ == "__main__":
    if sys.argv[1] == "child":
        child(sys.argv[2], int(sys.argv[3]))
    else:
        parent(int(sys.argv[1]))
