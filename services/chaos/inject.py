"""The injecting client: a plain client of the run's router that puts forged frames on every
data key of the run, with a routing attachment that delivers them at once."""

from __future__ import annotations

import logging
import time
from collections.abc import Callable

from common.bus import Bus, Keys, Publisher
from common.bus.watcher import Watcher
from common.config.bus import client_config
from common.messages import Message, WireError, decode, encode_routing
from common.runtime.model.dataflow import Dataflow
from services.chaos.forge import payloads

log = logging.getLogger("tidelink.chaos")

ROUND_S = 0.1  # an injection round every 0.1 s of wall time (10 Hz)
FLOOD_PER_KEY = 50_000  # what a flood puts on each key in all
MAX_ROUNDS = {"oversized": 3}  # 20 MB per key per round: a few make the point


def newest_frames(watcher: Watcher, keys: Keys) -> dict[tuple[str, str], Message]:
    """The newest frame of each stream, decoded (from the run's watch tap)."""
    out: dict[tuple[str, str], Message] = {}
    for f in watcher.latest(keys):
        try:
            out[(f.service, f.stream)] = decode(f.payload)
        except WireError:
            continue
    return out


def inject(
    connect: str,
    keys: Keys,
    flow: Dataflow,
    mode: str,
    *,
    window_s: float,
    running: Callable[[], bool],
) -> int:
    """Inject `mode` on every data key (the dataflow's outputs) for `window_s` seconds of wall
    time or while `running()`; returns the number of frames put."""
    put = 0
    with Bus(client_config(connect, None), keys, identity="monitor") as bus:
        watcher = Watcher(bus, keys.run, keys.vehicle)
        real = newest_frames(watcher, keys)
        pubs: dict[tuple[str, str], Publisher] = {}
        for link in flow.links:
            k = (link.source, link.stream)
            if k in real and k not in pubs:
                pubs[k] = bus.publisher_on(keys.stream(*k))
        if not pubs:
            raise RuntimeError(f"no frames of run {keys.root} to forge from (is it running?)")
        end = time.monotonic() + window_s
        rounds = 0
        while time.monotonic() < end and running() and rounds < MAX_ROUNDS.get(mode, 10**9):
            rounds += 1
            started = time.monotonic()
            for k, pub in pubs.items():
                msg = real[k]
                now_us = max(0, round(msg.stamp * 1e6))
                receivers: dict[str, tuple[int, ...]] = {
                    r: (now_us,) for r, _ in flow.receivers.get(k, ())
                }
                routing = encode_routing(0, receivers)
                frames = payloads(mode, msg)
                copies = 1 if mode != "flood" else max(1, FLOOD_PER_KEY // len(frames) // 50)
                for _ in range(copies):
                    for data in frames:
                        pub.put_bytes(data, routing)
                        put += 1
            if mode == "flood" and put >= FLOOD_PER_KEY * len(pubs):
                break
            # pacing the rounds, not waiting for a result
            time.sleep(max(0.0, ROUND_S - (time.monotonic() - started)))
            real |= newest_frames(watcher, keys)  # stamps keep up with the run
    return put
