"""Arrival at the goal, by the estimate, with hysteresis: a current carries a stopped hull off."""

from __future__ import annotations

import math

# the vehicle counts as arrived (and stops) this far inside the goal tolerance (m), at most
# half of it: its estimate may be off by decimetres, and a hull stopped just outside the
# tolerance ends no mission
ARRIVE_INSIDE_M = 0.5
# once arrived, the vehicle counts as having left again this far beyond the tolerance (m)
LEAVE_MARGIN_M = 0.5


class Arrival:
    """Whether the vehicle has arrived: its estimate well within the goal's tolerance. It
    stops there, and in still water stays; a current carries it off, so once its estimate is
    LEAVE_MARGIN_M beyond the tolerance it has not arrived any more, and is steered back."""

    def __init__(self, goal: tuple[float, float], tolerance_m: float) -> None:
        self.goal = goal
        self.arrive_m = tolerance_m - min(ARRIVE_INSIDE_M, 0.5 * tolerance_m)
        self.leave_m = tolerance_m + LEAVE_MARGIN_M
        self.arrived = False

    def update(self, x: float, y: float) -> bool:
        """Whether the vehicle at (x, y) (its estimate) has arrived."""
        d = math.hypot(x - self.goal[0], y - self.goal[1])
        if d <= self.arrive_m:
            self.arrived = True
        elif d > self.leave_m:
            self.arrived = False
        return self.arrived
