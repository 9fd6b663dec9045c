"""Sending clock ticks: each on a key naming its recipients, so only they wake up."""

from __future__ import annotations

from collections.abc import Iterable

from common.bus import Bus, Publisher
from common.messages import Tick, encode

# uses of a set of recipients before it gets a publisher of its own. A lockstep fleet's due
# sets vary (its look-ahead splits ticks): 16 vehicles met 188-214 sets in ~3200 ticks, most
# once or twice, and declaring their publishers cost the coordinator 1.6 s of a 37 s run
# (p50 2.4 ms, up to 40 ms each, on the tick's path); until then, one copy to each recipient
DECLARE_AFTER = 4


class TickSender:
    """Publishes Ticks to the services they are for (see Keys.tick).

    A tick that names due services goes to those; a stop tick, or one that names nobody
    (realtime start and clock ticks), goes to every service of the run.

    `express`: sent at once from the caller's thread, for the realtime clock, whose ticks
    set every service's time. Lockstep ticks go batched (express False): Zenoh sends a batch
    as soon as its link is free, so a tick waits for nothing, and the send leaves the
    coordinator's thread (an express put cost it 0.36-0.46 ms a tick while the services
    stepped). The default mission in lockstep, interleaved pairs on 2 cores, median wall:
    seed 1 13.2 -> 12.7 s, seed 2 13.4 -> 12.2 s, seed 3 11.7 -> 10.0 s; the toy loop's
    floor (trivial cores, nothing else busy) is the same either way (1.60 / 1.66 ms).
    """

    def __init__(self, bus: Bus, services: Iterable[str], *, express: bool) -> None:
        self._bus = bus
        self._express = express
        self._all = tuple(sorted(services))
        self._pubs: dict[tuple[str, ...], Publisher] = {}
        self._uses: dict[tuple[str, ...], int] = {}

    def put(self, tick: Tick) -> None:
        to = self._all if tick.stop or not tick.due else tuple(sorted(tick.due))
        if to not in self._pubs and len(to) > 1 and to != self._all:
            uses = self._uses[to] = self._uses.get(to, 0) + 1
            if uses < DECLARE_AFTER:
                # a set of recipients met rarely: a copy to each on its own key, which its
                # subscription (Keys.ticks_for) matches as it matches the set's
                data = encode(tick)
                for name in to:
                    self._publisher((name,)).put_bytes(data)
                return
        self._publisher(to).put(tick)

    def _publisher(self, to: tuple[str, ...]) -> Publisher:
        pub = self._pubs.get(to)
        if pub is None:
            key = self._bus.keys.tick(to)
            pub = self._pubs[to] = self._bus.publisher_on(key, express=self._express)
        return pub
