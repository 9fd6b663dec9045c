"""Whether a client's puts get through its router. Zenoh reports no error for a put: a router
whose access control denies it drops it silently, and a publisher would count it as sent."""

from __future__ import annotations

import threading
import time

from common.bus.bus import Bus

PROBE_EVERY_S = 0.1  # a probe put this often until one comes back (the listener's subscription
# has to reach the prober first: a client sends a put only once it knows of a subscriber)


def puts_reach_router(bus: Bus, key: str, *, timeout_s: float = 3.0) -> bool:
    """Put probes on `key` from `bus` and listen for them on a second session of the same
    config and identity, through the router: True once one arrives, False if none does
    within timeout_s (the router denies this identity's puts on `key`, or its subscription).
    A router session routes for itself: its own puts are not judged (True)."""
    if bus.cfg.mode != "client":
        return True
    got = threading.Event()
    with Bus(bus.cfg, bus.keys, identity=bus.identity) as listener:
        listener.subscribe_raw(key, lambda f: got.set())
        deadline = time.monotonic() + timeout_s
        while not got.is_set() and time.monotonic() < deadline:
            bus.put_raw(key, b"probe")
            got.wait(PROBE_EVERY_S)
    return got.is_set()
