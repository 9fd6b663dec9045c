"""A vehicle's trail for the Foxglove view: poses kept at a spacing, bounded, sent at a rate."""

from __future__ import annotations

import math
from collections import deque

from foxglove.messages import Pose

from services.foxglove.scene import yaw_pose


class Trail:
    """The recent poses of one vehicle track (true or estimated), thinned and bounded.

    A pose is kept when it lies `spacing_m` from the last kept one (a 20 Hz truth stream
    would otherwise send thousands of near-identical poses); the oldest go past `max_poses`.
    `due` says when to send the trail again: at most every `period_s` of mission time, so
    its size times its rate stays bounded however fast the run goes.
    """

    def __init__(self, *, spacing_m: float, max_poses: int, period_s: float) -> None:
        self.spacing_m = spacing_m
        self.period_s = period_s
        self._poses: deque[Pose] = deque(maxlen=max_poses)
        self._last_xy: tuple[float, float] | None = None
        self._sent_t = -math.inf

    def add(self, x: float, y: float, theta_rad: float) -> bool:
        """Keep this pose if it is far enough from the last kept one; True if kept."""
        if self._last_xy is not None:
            if math.hypot(x - self._last_xy[0], y - self._last_xy[1]) < self.spacing_m:
                return False
        self._last_xy = (x, y)
        self._poses.append(yaw_pose(x, y, theta_rad))
        return True

    def due(self, t_s: float) -> bool:
        """True (and the send time noted) if the trail was last sent period_s before t_s;
        a stamp earlier than the last send (a new run, a replay) restarts the clock."""
        if t_s - self._sent_t >= self.period_s or t_s < self._sent_t:
            self._sent_t = t_s
            return True
        return False

    @property
    def poses(self) -> list[Pose]:
        return list(self._poses)

    def __len__(self) -> int:
        return len(self._poses)
