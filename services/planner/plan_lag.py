"""How long a plan takes to reach the vehicle beyond the loop's delay, learned from the steps.

In realtime a replan is computed inside the planner's step: its path and the command sent
with it leave when the computation ends, while the vehicle runs on the commands it holds.
Planned from where the vehicle was when the step began, the path starts behind it (at
1.5 m/s a 0.4 s plan starts 0.6 m back, its first turn in the wrong place: a vehicle turning
at R_min has no room to catch up beside an obstacle). The pure core cannot read a clock, but
it sees the lag: the step after a plan comes that much later than one period. So it keeps
the last few lags and starts the next plan where the vehicle will be when that plan arrives
(their median further ahead along the commands sent); a plan that came later than that by
more than planner.late_plan_s is made again at once from the newest estimate (once: a second
slow plan is kept, rather than plan without end on a machine that is behind).

In lockstep and inproc a step takes no mission time: every lag is 0 and nothing changes.
"""

from __future__ import annotations

import statistics
from collections import deque

LAGS_KEPT = 5  # a median of the last plans' lags: one slow plan moves it by a rank at most
# the most a plan is started ahead: a lag of seconds is a process stopped or starved, not a
# plan's computing time to expect again (the late rule makes such a plan again)
MAX_EXPECTED_S = 2.0


class PlanLag:
    """The lag of the planner's plans, observed step by step."""

    def __init__(self, period_s: float, late_plan_s: float) -> None:
        self.period_s = period_s
        self.late_plan_s = late_plan_s
        self._lags: deque[float] = deque(maxlen=LAGS_KEPT)
        self._last_step_t: float | None = None
        self._plan_step_t: float | None = None  # the step that made the path in force
        self._assumed = 0.0  # the lag that path was planned for
        self._remade = False  # that path was made again because the one before came late
        self.late = 0  # plans made again for coming late

    @property
    def expected_s(self) -> float:
        """The lag to plan for now (s): the median of the last ones (at most MAX_EXPECTED_S),
        0 before any."""
        return min(statistics.median(self._lags), MAX_EXPECTED_S) if self._lags else 0.0

    def step(self, t: float) -> float | None:
        """A step begins at t. If the step before made a plan, learn its lag; return by how
        much it came later than planned for when that exceeds late_plan_s (and the plan was
        not itself made again for being late), else None."""
        prev, self._last_step_t = self._last_step_t, t
        if prev is None or self._plan_step_t != prev:
            return None
        over = t - prev - self.period_s
        lag = over if over > 0.5 * self.period_s else 0.0  # a step on time, to rounding
        self._lags.append(lag)
        beyond = lag - self._assumed
        return beyond if beyond > self.late_plan_s and not self._remade else None

    def planned(self, t: float, *, assumed_s: float, remade: bool) -> None:
        """The step beginning at t made a plan for a lag of assumed_s; remade: because the
        one before came late."""
        self._plan_step_t, self._assumed, self._remade = t, assumed_s, remade
        self.late += remade
