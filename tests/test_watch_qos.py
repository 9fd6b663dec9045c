"""The watch tap's QoS holds: a watcher that stops reading (SIGSTOP) stalls neither the tap's
publisher nor any other watcher. Real processes: a router, two subscribers, this publisher."""

from __future__ import annotations

import signal
import time

import pytest
from helpers.launch_proc import REPO, Tidelink

from common.bus import Bus, Keys
from common.config.bus import BusConfig
from common.runtime.processes.children import free_port

pytestmark = pytest.mark.slow

# A subscriber that prints, once a second, the longest gap between two samples it received.
GAPS = """
import sys, time
sys.path.insert(0, {repo!r})
from common.bus import Bus, Keys
from common.config.bus import BusConfig
last = [time.monotonic()]; worst = [0.0]
def on(f):
    now = time.monotonic(); worst[0] = max(worst[0], now - last[0]); last[0] = now
with Bus(BusConfig(mode="client", connect=({endpoint!r},)), Keys("q", "q")) as bus:
    bus.subscribe_raw({key!r}, on)
    print("ready", flush=True)
    while True:
        time.sleep(1.0)
        print(f"gap {{worst[0]:.3f}}", flush=True); worst[0] = 0.0
"""

PAYLOAD = b"x" * 20_000  # 10 MB/s at 500 Hz: a stopped reader's buffers fill in a second or two
SECONDS = 8.0


def _subscriber(endpoint: str, key: str) -> Tidelink:
    code = GAPS.format(repo=str(REPO), endpoint=endpoint, key=key)
    t = Tidelink.python("-c", code)
    t.wait_for(r"^ready$", 30.0, stdout=True)
    return t


def test_a_stopped_watcher_stalls_neither_the_tap_nor_another_watcher() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    keys = Keys("qos", "auv1")
    key = keys.watch("vehicle", "truth")
    with Tidelink("router", "--listen", endpoint) as router:
        router.wait_for(r"listening", 30.0, stdout=True)
        with _subscriber(endpoint, key) as good, _subscriber(endpoint, key) as stopped:
            stopped.signal(signal.SIGSTOP)
            try:
                cfg = BusConfig(mode="client", connect=(endpoint,))
                worst_put = 0.0
                with Bus(cfg, keys) as bus:
                    pub = bus.monitoring_publisher(key)
                    t_end = time.monotonic() + SECONDS
                    while time.monotonic() < t_end:
                        t0 = time.monotonic()
                        pub.put_bytes(PAYLOAD)
                        worst_put = max(worst_put, time.monotonic() - t0)
                        time.sleep(0.002)  # pacing a 500 Hz publisher, not a wait for a result
                gaps = [float(line.split()[1]) for line in good.out if line.startswith("gap")]
            finally:
                stopped.signal(signal.SIGCONT)
        router.signal(signal.SIGINT)
    # BLOCK here stalled the publisher 4.6 s and the other subscriber 5 s (README)
    assert worst_put < 0.5, f"the tap's put blocked {worst_put:.2f} s"
    assert len(gaps) >= SECONDS - 2
    assert max(gaps[1:]) < 0.5, f"the other watcher starved: gaps {gaps}"
