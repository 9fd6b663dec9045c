"""The realtime mission clock: scaled wall time since the start Tick.

Services set their clock from the first Tick they see and correct it with every later one
(distributed.realtime_service), so the realtime driver re-publishes the current mission time:
at once when a service (re)appears, and periodically, so a restarted or late remote service
joins at the right time and every service's clock converges on the launcher's.
"""

from __future__ import annotations

import time

from common.messages import Tick
from common.runtime.distributed.ticks import TickSender


class MissionClock:
    """Publishes Ticks carrying the mission time; time starts at `start()`."""

    def __init__(self, pub: TickSender, scale: float) -> None:
        self.pub = pub
        self.scale = scale
        self.t0: float | None = None
        self.ticks = 0

    @property
    def started(self) -> bool:
        return self.t0 is not None

    def start(self) -> None:
        """Time 0 is now: the start Tick carries exactly 0."""
        self.t0 = time.monotonic()
        self.pub.put(Tick(stamp=0.0, tick=0, time_us=0))
        self.ticks = 1

    def now_us(self) -> int:
        if self.t0 is None:
            return 0
        return round((time.monotonic() - self.t0) * self.scale * 1e6)

    def tell(self, *, stop: bool = False) -> int:
        """Publish the current mission time (us); stop=True ends the run for every service."""
        t_us = self.now_us()
        self.pub.put(Tick(stamp=t_us / 1e6, tick=self.ticks, time_us=t_us, stop=stop))
        self.ticks += 1
        return t_us
