"""Sending clock ticks: each on a key naming its recipients, so only they wake up."""

from __future__ import annotations

from collections.abc import Iterable

from common.bus import Bus, Publisher
from common.messages import Tick


class TickSender:
    """Publishes Ticks to the services they are for (see Keys.tick).

    A tick that names due services goes to those; a stop tick, or one that names nobody
    (realtime start and clock ticks), goes to every service of the run.
    """

    def __init__(self, bus: Bus, services: Iterable[str]) -> None:
        self._bus = bus
        self._all = tuple(sorted(services))
        self._pubs: dict[tuple[str, ...], Publisher] = {}

    def put(self, tick: Tick) -> None:
        to = self._all if tick.stop or not tick.due else tuple(sorted(tick.due))
        pub = self._pubs.get(to)
        if pub is None:
            # express: the recipients wait on this tick, it must not sit in a batch
            pub = self._pubs[to] = self._bus.publisher_on(self._bus.keys.tick(to), express=True)
        pub.put(tick)
