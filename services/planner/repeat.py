"""The path in force sent again while the controller is onboard, so a lost message is not final.

With ``controller.placement = "onboard"`` only path messages cross the link, once per replan,
and nothing comes back to say which one arrived: over a lossy link (50 % loss on an acoustic
modem is no rarity) one lost message left the tracker on an older path, or on none, for the
rest of the run while the planner went on as if it followed the newest. The planner sends
the path in force again every `planner.path_repeat_s`, restamped (it is sent then); the
tracker takes a path only when its number is newer than the one it follows, and the run's
readers count a path once, by number (services/mission/metrics.py `distinct_paths`).
"""

from __future__ import annotations

import msgspec

from common.messages import PathMsg


class PathRepeat:
    """The last path message sent and when: sent again once every `every_s` seconds."""

    def __init__(self, every_s: float) -> None:
        self.every_s = every_s  # 0: never
        self._last: PathMsg | None = None
        self._sent_t = 0.0

    def sent(self, t: float, msg: PathMsg) -> None:
        """A path message sent at t (s)."""
        self._last, self._sent_t = msg, t

    def outgoing(self, t: float, new: PathMsg | None) -> PathMsg | None:
        """The path message to send at t: `new` (a path just put in force), else the one in
        force when it is due again (`due`), else None."""
        if new is None:
            return self.due(t)
        self.sent(t, new)
        return new

    def due(self, t: float) -> PathMsg | None:
        """The path in force restamped t, when it is due to be sent again at t; else None."""
        if self._last is None or self.every_s <= 0.0 or t - self._sent_t < self.every_s - 1e-9:
            return None
        self.sent(t, msgspec.structs.replace(self._last, stamp=t))
        return self._last
