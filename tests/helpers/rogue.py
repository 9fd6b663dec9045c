"""A hostile client of a secured run (tests/test_security_live.py): it holds a valid,
CA-signed certificate (by default the monitor's) and tries to take the run over.

Run as ``python -m helpers.rogue --connect EP --certs DIR [--identity monitor] [--run RUN]
[--vehicle V] [--rate HZ]`` with the tests directory on PYTHONPATH. It waits for the router,
then at `rate` Hz, until the run announces its end (or SIGTERM):
- puts a well-formed VelocityCommand (envelope source "planner", fresh stamp from the newest
  vehicle status it watched, rising seq) with a routing attachment that delivers it to the
  vehicle now, on the planner's command key;
- puts a stop Tick addressed to every service on the clock's tick key;
- declares the planner's liveliness token;
and watches the run through the tap like a monitor. It prints ``connected`` once its session
is open, then one JSON line: what it sent, and what it watched (frames, and whether it saw
the run's end) — proof that it was connected during the run.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

from common.bus import Bus, Keys
from common.bus.watcher import WatchedFrame, Watcher
from common.config.bus import client_config
from common.messages import Tick, VehicleStatus, VelocityCommand, decode, encode, encode_routing
from common.runtime.processes.children import wait_for_endpoint
from common.runtime.processes.signals import Shutdown, install_shutdown_handlers

SERVICES = ("estimator", "planner", "sensor", "vehicle")


def main() -> int:
    p = argparse.ArgumentParser()
    p.add_argument("--connect", required=True)
    p.add_argument("--certs", default=None)
    p.add_argument("--identity", default="monitor")
    p.add_argument("--run", default="demo")
    p.add_argument("--vehicle", default="auv1")
    p.add_argument("--rate", type=float, default=100.0)
    p.add_argument("--timeout", type=float, default=120.0)
    a = p.parse_args()
    install_shutdown_handlers()
    keys = Keys(a.run, a.vehicle)
    sent = {"cmd": 0, "stop_ticks": 0, "watched": 0, "sent_while_watching": 0}
    saw_end = False
    deadline = time.monotonic() + a.timeout
    if not wait_for_endpoint(a.connect, a.timeout):
        print(json.dumps({"error": f"no router at {a.connect}"}), flush=True)
        return 3
    try:
        with Bus(client_config(a.connect, a.certs), keys, identity=a.identity) as bus:
            print("connected", flush=True)
            watcher = Watcher(bus, a.run, a.vehicle)
            watcher.start()
            cmd = bus.publisher_on(keys.stream("planner", "cmd"))
            stop = bus.publisher_on(keys.tick(SERVICES))
            bus.declare_alive("planner")
            stamp = 0.0
            seq = 1 << 40  # newer than anything the planner will send in a test run
            while not saw_end and time.monotonic() < deadline:
                seq += 1
                now_us = int(stamp * 1e6)
                routing = encode_routing(0, {"vehicle": (now_us,)})
                cmd.put_bytes(
                    encode(
                        VelocityCommand(
                            stamp=stamp, source="planner", seq=seq, v=1.5, w=0.5, path_id=1
                        )
                    ),
                    routing,
                )
                stop.put(Tick(stamp=stamp, tick=0, time_us=now_us, stop=True))
                sent["cmd"] += 1
                sent["stop_ticks"] += 1
                if sent["watched"]:
                    sent["sent_while_watching"] += 1
                # drain what the tap sent meanwhile, pacing the puts at `rate`
                until = time.monotonic() + 1.0 / a.rate
                while (left := until - time.monotonic()) > 0:
                    ev = watcher.get(timeout=left)
                    if not isinstance(ev, WatchedFrame):
                        continue
                    sent["watched"] += 1
                    if ev.stream == "end":
                        saw_end = True
                    elif ev.stream == "status":
                        msg = decode(ev.payload)
                        if isinstance(msg, VehicleStatus):
                            stamp = max(stamp, msg.stamp)
    except Shutdown:
        pass
    print(json.dumps({**sent, "saw_end": saw_end}), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
