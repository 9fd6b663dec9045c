"""The child process of tests/test_bus_procs.py: a second Zenoh peer that sends or idles.

Run as ``python -m helpers.bus_peer ROLE --endpoint tcp/127.0.0.1:PORT --run RUN`` with the
tests directory on PYTHONPATH. Roles:

- ``exchange``: connect, wait for the parent's liveliness token, publish one message of each
  type (one stream per type), then wait for the parent's token to vanish and exit 0.
- ``garbage``: like exchange, but on one stream: garbage, valid NavFix (seq 1), a wrong-version
  frame, valid NavFix (seq 2).
- ``idle``: listen, declare subscribers (inbox and callback), a liveliness watch and a token,
  print ``ready``, and block in the inbox loop until SIGTERM/SIGINT; exit 0 on Shutdown.

Exit codes: 0 done, 3 the parent never appeared, 4 the parent never went away.
"""

from __future__ import annotations

import argparse
import sys
import time

import msgpack

from common.bus import Bus, Inbox, Keys, Liveliness
from common.config.bus import BusConfig
from common.messages import Message, NavFix
from common.runtime.processes.signals import Shutdown, install_shutdown_handlers
from helpers.samples import one_of_each

PARENT = "parent"
PEER = "peer"
VEHICLE = "auv1"
GARBAGE_STREAM = "nav"
# What the garbage role sends on GARBAGE_STREAM before each valid message.
NOT_MSGPACK = b"\xc1\xc1 this is not msgpack"
WRONG_VERSION = bytes(msgpack.packb([99, {"type": "NavFix"}]))


def stream_of(cls: type[Message]) -> str:
    """The stream each message type travels on in the exchange role."""
    return cls.__name__.lower()


def garbage_navs() -> list[NavFix]:
    """The two valid messages the garbage role sends after each bad payload."""
    base = one_of_each()[0]
    assert isinstance(base, NavFix)
    return [
        NavFix(
            stamp=base.stamp + i,
            source=PEER,
            seq=i,
            sent=base.sent,
            x=base.x,
            y=base.y,
            heading=base.heading,
            speed=base.speed,
            std_xy=base.std_xy,
            std_heading=base.std_heading,
            std_speed=base.std_speed,
        )
        for i in (1, 2)
    ]


def _wait_liveliness(inbox: Inbox, alive: bool, timeout_s: float) -> bool:
    """Wait for a liveliness event with this `alive` value (other events are ignored)."""
    deadline = time.monotonic() + timeout_s
    while (left := deadline - time.monotonic()) > 0:
        ev = inbox.get(timeout=left)
        if isinstance(ev, Liveliness) and ev.alive is alive:
            return True
    return False


def send(bus: Bus, keys: Keys, role: str) -> int:
    """The exchange and garbage roles."""
    inbox = Inbox()
    bus.watch_alive(inbox, keys.alive(PARENT))
    # The parent declares its subscriptions before its token, and Zenoh delivers declarations
    # in order: once we see the token, the subscriptions are known here.
    if not _wait_liveliness(inbox, True, 20.0):
        return 3
    if role == "exchange":
        for msg in one_of_each():
            bus.publisher(PEER, stream_of(type(msg))).put(msg)
    else:
        pub = bus.publisher(PEER, GARBAGE_STREAM)
        first, second = garbage_navs()
        bus.put_raw(pub.key, NOT_MSGPACK)
        pub.put(first)
        bus.put_raw(pub.key, WRONG_VERSION)
        pub.put(second)
    # Stay until the parent has everything and closes (its token vanishes).
    return 0 if _wait_liveliness(inbox, False, 20.0) else 4


def idle(bus: Bus, keys: Keys) -> int:
    """The idle role: everything that starts Zenoh threads, then block until a signal."""
    inbox = Inbox()
    got: list[str] = []
    bus.subscribe(keys.stream(PARENT, "*"), inbox)
    bus.subscribe_raw(keys.everything, lambda f: got.append(f.key))
    bus.watch_alive(inbox)
    bus.declare_alive(PEER)
    print("ready", flush=True)
    while True:
        inbox.get(timeout=1.0)


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("role", choices=("exchange", "garbage", "idle"))
    p.add_argument("--endpoint", required=True, help="tcp/127.0.0.1:PORT")
    p.add_argument("--run", required=True, help="run id of the keys")
    a = p.parse_args()
    keys = Keys(run=a.run, vehicle=VEHICLE)
    if a.role == "idle":
        install_shutdown_handlers()
        try:
            with Bus(BusConfig(listen=(a.endpoint,)), keys) as bus:
                return idle(bus, keys)
        except Shutdown:
            return 0
    with Bus(BusConfig(connect=(a.endpoint,)), keys) as bus:
        return send(bus, keys, a.role)


if __name__ == "__main__":
    sys.exit(main())
