"""The watch tap's QoS holds: a watcher that stops reading (SIGSTOP) stalls neither the tap's
publisher nor any other watcher. Real processes: a router, two subscribers, this publisher."""

from __future__ import annotations

import signal
import time

import pytest
from helpers.launch_proc import REPO, Tidelink

from common.bus import Bus, Keys
from common.bus.tap import WatchTap
from common.config.bus import BusConfig
from common.runtime.processes.children import free_port

pytestmark = pytest.mark.slow

# A subscriber that prints, once a second, the longest gap between two samples it received.
GAPS = """
import sys, time
sys.path.insert(0, {repo!r})
from common.bus import Bus, Keys
from common.bus.tap import WatchTap
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


@pytest.mark.exclusive  # its bounds are wall-clock gaps, which the machine's load stretches
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
    # BLOCK here stalled the publisher 4.6 s and the other subscriber 5 s (docs/notes/0002);
    # a loaded 2-core machine's scheduler alone has left a reader 0.7 s without a sample
    assert worst_put < 1.0, f"the tap's put blocked {worst_put:.2f} s"
    assert len(gaps) >= SECONDS - 2
    assert max(gaps[1:]) < 1.0, f"the other watcher starved: gaps {gaps}"


# A watcher that reads slowly (a loaded machine's monitor) and says when the run's end came.
SLOW_END = """
import sys, time
sys.path.insert(0, {repo!r})
from common.bus import Bus, Keys
from common.bus.tap import WatchTap
from common.config.bus import BusConfig
def on(f):
    if f.key == {end!r}:
        print("end", flush=True)
    else:
        time.sleep(0.002)  # the slowness under test (a loaded watcher), not a wait
with Bus(BusConfig(mode="client", connect=({endpoint!r},)), Keys("q", "q")) as bus:
    bus.subscribe_raw({watch!r}, on)
    print("ready", flush=True)
    while True:  # the callbacks do the work; the test ends this process
        time.sleep(1.0)
"""


# exclusive: its outcome depends on the machine. A watcher whose queue at the router stays
# full for longer than the router's block-close delay (common/bus/session.py) has its
# session closed, and the end queued for it with it: with the delay at 1 s the end did not
# come in 120 s on fresh clones 72 and 73 and on 4 of 7 tries alone (2026-11-29)
@pytest.mark.exclusive
def test_a_slow_watcher_still_gets_the_runs_end_behind_a_stopped_one() -> None:
    # the tap's copies are DROP: a slow watcher loses some; the RunEnd, sent once the run is
    # over, must reach it all the same (as DROP it reached neither watcher here), without
    # the stopped watcher holding up the end of the run
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    keys = Keys("qos", "auv1")
    watch = keys.watch("vehicle", "truth").rsplit("/", 2)[0] + "/**"
    code = SLOW_END.format(repo=str(REPO), endpoint=endpoint, end=keys.end, watch=watch)
    with Tidelink("router", "--listen", endpoint) as router:
        router.wait_for(r"listening", 30.0, stdout=True)
        with Tidelink.python("-c", code) as slow, _subscriber(endpoint, watch) as stopped:
            slow.wait_for(r"^ready$", 30.0, stdout=True)
            stopped.signal(signal.SIGSTOP)
            try:
                with Bus(BusConfig(mode="client", connect=(endpoint,)), keys) as bus:
                    tap = WatchTap(bus, keys, {})
                    pub = bus.monitoring_publisher(keys.watch("vehicle", "truth"))
                    for _ in range(3000):  # a burst the slow watcher cannot keep up with
                        pub.put_bytes(b"x" * 2000)
                    t0 = time.monotonic()
                    tap.end("goal", 12.5, 250)
                    # closing right after, as a launcher does
                closed_after = time.monotonic() - t0
                # the end comes after the copies already queued for the slow watcher: the
                # burst sits in the sockets' buffers, ~5 s of reading at 2 ms a frame here,
                # over 30 s once on a loaded machine (fresh clone 57), hence the bound
                slow.wait_for(r"^end$", 120.0, stdout=True)
            finally:
                stopped.signal(signal.SIGCONT)
        router.signal(signal.SIGINT)
    assert closed_after < 3.0, f"the end held the run up {closed_after:.2f} s"
