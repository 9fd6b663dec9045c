"""TickSender over real Zenoh: every recipient of a tick gets it once, on a set's own key only
once that set has come back (ticks.py), and nobody else gets it."""

from __future__ import annotations

import time

from common.bus import Bus, Inbox, Keys, Received
from common.config.bus import BusConfig
from common.messages import Tick
from common.runtime.distributed.ticks import DECLARE_AFTER, TickSender
from common.runtime.processes.children import free_port

NAMES = ("auv1.planner", "auv1.sensor", "auv2.planner", "auv2.sensor")


def _tick(k: int, due: tuple[str, ...], *, stop: bool = False) -> Tick:
    return Tick(stamp=k / 10, tick=k, time_us=k * 100_000, watermarks={}, due=due, stop=stop)


def _ticks(inbox: Inbox, until: int, timeout_s: float = 10.0) -> list[tuple[str, int]]:
    """(key, tick) of every tick taken, until tick `until` came (or the timeout)."""
    got: list[tuple[str, int]] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        ev = inbox.get(timeout=0.1)
        if isinstance(ev, Received) and isinstance(ev.msg, Tick):
            got.append((ev.key, ev.msg.tick))
            if ev.msg.tick == until:
                break
    return got


def test_each_recipient_gets_each_tick_once_and_a_frequent_set_its_own_key() -> None:
    keys = Keys("tickrun", "fleet")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    pair = ("auv1.planner", "auv2.sensor")
    plan: list[Tick] = [_tick(k, pair) for k in range(1, DECLARE_AFTER + 2)]
    plan += [_tick(10, ("auv1.sensor",)), _tick(11, ()), _tick(12, pair, stop=True)]
    with Bus(BusConfig(mode="router", listen=(endpoint,)), keys) as clock:
        inboxes: dict[str, Inbox] = {}
        clients = []
        for name in NAMES:
            bus = Bus(BusConfig(mode="client", connect=(endpoint,)), keys).__enter__()
            clients.append(bus)
            inboxes[name] = Inbox()
            bus.subscribe(keys.ticks_for(name), inboxes[name])
        try:
            sender = TickSender(clock, NAMES, express=False)
            # tick 0 to everyone until each has one: every subscription reached the router
            heard: set[str] = set()
            deadline = time.monotonic() + 10.0
            while heard != set(NAMES) and time.monotonic() < deadline:
                sender.put(_tick(0, ()))
                heard |= {n for n in NAMES if n in heard or _ticks(inboxes[n], 0, 0.1)}
            assert heard == set(NAMES), heard
            for tick in plan:
                sender.put(tick)
            got = {name: [g for g in _ticks(inboxes[name], 12) if g[1]] for name in NAMES}
        finally:
            for bus in clients:
                bus.__exit__(None, None, None)
    for name in pair:
        mine = [t.tick for t in plan if name in t.due or not t.due or t.stop]
        assert [k for _, k in got[name]] == mine, (name, got[name])
        keys_used = [key for key, _ in got[name]]
        # rare: on the recipient's own key; from the DECLARE_AFTER-th use on: the set's key
        own, shared = keys.tick([name]), keys.tick(pair)
        assert keys_used[: DECLARE_AFTER - 1] == [own] * (DECLARE_AFTER - 1)
        assert keys_used[DECLARE_AFTER - 1 : DECLARE_AFTER + 1] == [shared, shared]
    # the others: only the ticks naming them, or nobody (everyone), and the stop
    assert [k for _, k in got["auv1.sensor"]] == [10, 11, 12]
    assert [k for _, k in got["auv2.planner"]] == [11, 12]
