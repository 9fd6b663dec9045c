"""Sending clock ticks: each on a key naming its recipients, so only they wake up."""

from __future__ import annotations

from collections.abc import Iterable

from common.bus import Bus, Publisher
from common.messages import Tick


class TickSender:
    """Publishes Ticks to the services they are for (see Keys.tick).

    A tick that names due services goes to those; a stop tick, or one that names nobody
    (realtime start and clock ticks), goes to every service of the run.

    `express`: sent at once from the caller's thread, for the realtime clock, whose ticks
    set every service's time. Lockstep ticks go batched (express False): Zenoh sends a batch
    as soon as its link is free, so a tick waits for nothing, and the send leaves the
    coordinator's thread, which an express put held while the services stepped
    (docs/notes/0017-lockstep-ticks-batched.md).
    """

    def __init__(self, bus: Bus, services: Iterable[str], *, express: bool) -> None:
        self._bus = bus
        self._express = express
        self._all = tuple(sorted(services))
        self._pubs: dict[tuple[str, ...], Publisher] = {}

    def put(self, tick: Tick) -> None:
        to = self._all if tick.stop or not tick.due else tuple(sorted(tick.due))
        pub = self._pubs.get(to)
        if pub is None:
            key = self._bus.keys.tick(to)
            pub = self._pubs[to] = self._bus.publisher_on(key, express=self._express)
        pub.put(tick)
