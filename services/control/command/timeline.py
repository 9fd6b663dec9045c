"""What the vehicle applies, as the planner expects it: the commands sent and when each arrives.

The planner keeps a short history of the commands it has sent, each with the time it expects
the vehicle to receive it (its stamp plus the expected downlink delay when it was sent). At
time tau the vehicle applies, by its watchdog's rules, the newest command (by stamp) it has
received: the entry of that command's schedule for tau, HOLD after its last entry
(common/control/schedule.py, the vehicle's own code for it), IDLE (0, 0) before any. So the
state at the time a new command takes effect is predicted from the estimate with the commands
still in flight, not with a constant twist.

Pruning: once a command is expected to have arrived by the newest estimate's stamp, every
older one is superseded for all later times, so it is dropped. What stays is the commands in
flight around the estimate's age plus the downlink delay: ~(age + delay) / period of them.
"""

from __future__ import annotations

import math
from bisect import bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from common.config.vehicle import WatchdogConfig
from common.control import Schedule
from services.control.command.response import Pose, ResponseModel


@dataclass(frozen=True, kw_only=True, slots=True)
class Sent:
    """One command as sent: its stamp, its expected arrival at the vehicle and its schedule
    there (the stamp kept apart from the schedule's starts: predictions compare it often)."""

    stamp: float
    arrival: float
    schedule: Schedule


class CommandTimeline:
    """The commands sent, their expected arrivals, and the vehicle's state predicted under them."""

    def __init__(self, watchdog: WatchdogConfig, v_min: float, idle_v: float = 0.0) -> None:
        self._watchdog = watchdog
        self._v_min = v_min
        self._idle = Schedule(idle_v=idle_v)  # before any command: a start under way holds
        self.sent: list[Sent] = []  # in the order sent (stamps non-decreasing)
        # `sent` by expected arrival (ties: in the order sent), as (arrivals, stamps, in_force):
        # in_force[p] is the command in force once the first p of them have arrived (`_in_force`
        # of those: None for p = 0); None: to be built again (add, forget_before and clear
        # change `sent`)
        self._arrivals: tuple[list[float], list[float], list[Sent | None]] | None = None

    def add(
        self,
        stamp: float,
        arrival: float,
        step_s: float,
        vs: Sequence[float],
        ws: Sequence[float],
    ) -> None:
        """Record a command stamped `stamp` with entries (vs[k], ws[k]) every step_s (the values
        as the vehicle will read them off the wire), expected at the vehicle at `arrival`."""
        sched = Schedule.of_command(stamp, step_s, vs, ws, self._watchdog, self._v_min)
        self.sent.append(Sent(stamp=sched.starts[0], arrival=arrival, schedule=sched))
        self._arrivals = None

    def _in_force(self, t: float) -> Sent | None:
        """The newest command (by stamp) expected to have arrived by time t, if any."""
        best: Sent | None = None
        for s in self.sent:
            if s.arrival <= t and (best is None or s.stamp > best.stamp):
                best = s
        return best

    def schedule_at(self, t: float) -> Schedule:
        """The schedule in force at the vehicle at time t (IDLE before any command)."""
        cur = self._in_force(t)
        return self._idle if cur is None else cur.schedule

    def forget_before(self, t: float) -> None:
        """Drop the commands superseded at the vehicle by time t (t: the estimate's stamp)."""
        cur = self._in_force(t)
        if cur is not None:
            self.sent = [s for s in self.sent if s.stamp >= cur.stamp]
            self._arrivals = None

    def clear(self) -> None:
        self.sent.clear()
        self._arrivals = None

    def _by_arrival(self) -> tuple[list[float], list[float], list[Sent | None]]:
        """The commands sent by expected arrival (ties: as sent): their arrivals and stamps,
        and the command in force after each prefix of them (`_in_force`: the newest by stamp,
        the first sent of equal stamps; None before the first)."""
        if self._arrivals is None:
            order = sorted(enumerate(self.sent), key=lambda e: e[1].arrival)
            in_force: list[Sent | None] = [None]
            cur: Sent | None = None
            cur_i = -1  # cur's index in `sent`
            for i, s in order:
                if cur is None or s.stamp > cur.stamp or (s.stamp == cur.stamp and i < cur_i):
                    cur, cur_i = s, i
                in_force.append(cur)
            self._arrivals = (
                [s.arrival for _, s in order],
                [s.stamp for _, s in order],
                in_force,
            )
        return self._arrivals

    def predict(
        self, pose: Pose, t_a: float, t_b: float, model: ResponseModel, twist_only: bool = False
    ) -> Pose:
        """The state at t_b from `pose` at t_a, the vehicle applying the commands sent;
        `twist_only`: its twist alone (ResponseModel.advance)."""
        # the commands by arrival swept once, the command in force after each prefix of them
        # built once per change of `sent` (a tick asks ~5 predictions of ~20 commands), rather
        # than `_in_force`'s scan of every command sent for each command in force: the same
        # commands in force, from the same times
        arrivals, stamps, in_force = self._by_arrival()
        advance, idle = model.advance, self._idle
        n = len(arrivals)
        t = t_a
        while t < t_b:
            # in force at t (`_in_force`): the newest by stamp of those arrived by t
            p = bisect_right(arrivals, t)  # arrivals[:p]: arrived by t
            cur = in_force[p]
            # it lasts until a newer one arrives (by t_b at the latest): the first to arrive
            # after t with a newer stamp
            end = t_b
            newer_than = -math.inf if cur is None else cur.stamp
            for q in range(p, n):
                if arrivals[q] >= t_b:
                    break
                if stamps[q] > newer_than:
                    end = arrivals[q]
                    break
            sched = idle if cur is None else cur.schedule
            # within, the applied command changes only at the schedule's own transitions
            # (all before `end`): one call for the span's pieces, not one per piece
            for c, v, w in sched.pieces_between(t, end):
                pose = advance(pose, v, w, c - t, twist_only)
                t = c
        return pose
