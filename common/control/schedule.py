"""What a vehicle applies from one command: its entries in turn, then HOLD, then FAILSAFE.

Both ends of the command link use it: the vehicle's watchdog (services/vehicle/watchdog.py)
runs the schedule of the command in force, and the planner models with the same schedule
what the vehicle will apply from the commands it has sent (services/control/command/timeline.py), so
the two cannot disagree on what a sequence means. A command carries entries k = 0..n (n = 0:
a single command), entry k in force from stamp + k * step_s (packet-based predictive
control); HOLD counts from the start of the last entry (hold_after_s), FAILSAFE likewise
(failsafe_after_s); the rules are in the watchdog's docstring.
"""

from __future__ import annotations

import math
from bisect import bisect_left, bisect_right
from collections.abc import Sequence
from dataclasses import dataclass

from common.config.vehicle import WatchdogConfig
from common.messages import VehicleMode


@dataclass(frozen=True, kw_only=True, slots=True)
class Applied:
    """What the vehicle applies at one instant: mode, command (v, w) and command age."""

    mode: VehicleMode
    v: float
    w: float
    age_s: float


@dataclass(frozen=True, kw_only=True, slots=True)
class Schedule:
    """The command as a function of time until the next accepted command (immutable).

    Before any command: IDLE, (idle_v, 0): at rest, or a vehicle that starts under way
    holding its speed and heading. Then RUN with entry k, (vs[k], ws[k]), from starts[k]
    (entry 0 also before its start) until t_hold, then HOLD from the last entry: the speed
    command falls to v_floor at `decel` (inf: at once), w = 0 (FAILSAFE from t_fail). The
    plant integrator keeps these per time window and splits its steps at the entry starts and
    the mode changes (transitions_between), so a command's effect does not depend on when the
    plant happens to be integrated.
    """

    starts: tuple[float, ...] = ()  # starts[k] = stamp + k * step_s; () before any command
    vs: tuple[float, ...] = ()  # (n + 1,) clamped surge speeds (m/s)
    ws: tuple[float, ...] = ()  # (n + 1,) clamped yaw rates (rad/s)
    t_hold: float = math.inf  # starts[-1] + hold_after_s
    t_fail: float = math.inf  # starts[-1] + failsafe_after_s
    decel: float = 0.0
    v_floor: float = 0.0
    idle_v: float = 0.0  # the speed held before any command (m/s)

    @property
    def stamp(self) -> float | None:
        """The stamp of the command this schedule comes from (None before any)."""
        return self.starts[0] if self.starts else None

    def at(self, t: float) -> Applied:
        """The command in force at time t (held constant over an integration step from t)."""
        if not self.starts:
            return Applied(mode="IDLE", v=self.idle_v, w=0.0, age_s=0.0)
        # the entry that started last, at t (entry 0 also before its start)
        k = max(0, bisect_right(self.starts, t) - 1) if len(self.starts) > 1 else 0
        # the age of the entry in force; one from the future (clock skew) counts as fresh
        age = max(0.0, t - self.starts[k])
        if t < self.t_hold:
            return Applied(mode="RUN", v=self.vs[k], w=self.ws[k], age_s=age)
        mode: VehicleMode = "FAILSAFE" if t >= self.t_fail else "HOLD"
        return Applied(mode=mode, v=self._held_v(t), w=0.0, age_s=age)

    def vw_at(self, t: float) -> tuple[float, float]:
        """The command (v, w) of `at(t)`, without building its Applied: the planner's
        predictions and the plant's integrator ask this at every step."""
        if not self.starts:
            return self.idle_v, 0.0
        if t < self.t_hold:
            k = max(0, bisect_right(self.starts, t) - 1) if len(self.starts) > 1 else 0
            return self.vs[k], self.ws[k]
        return self._held_v(t), 0.0

    def _held_v(self, t: float) -> float:
        """The speed commanded in HOLD / FAILSAFE (k = n: t_hold is past the last start): the
        last entry's, lowered at `decel` (w = 0: the heading is held); an infinite rate drops
        it at once (inf * 0 would be NaN at t_hold itself)."""
        v_last = self.vs[-1]
        drop = math.inf if math.isinf(self.decel) else self.decel * (t - self.t_hold)
        return min(v_last, max(self.v_floor, v_last - drop))

    def transitions_between(self, t_a: float, t_b: float) -> list[float]:
        """The times in (t_a, t_b) at which this schedule changes by itself: the starts of
        entries 1..n, t_hold and t_fail."""
        out = [x for x in (self.t_hold, self.t_fail) if t_a < x < t_b]
        if len(self.starts) > 1:
            i = max(1, bisect_right(self.starts, t_a))
            out.extend(self.starts[i : bisect_left(self.starts, t_b)])
        return out

    def pieces_between(self, t_a: float, t_b: float) -> list[tuple[float, float, float]]:
        """The pieces of [t_a, t_b) over which the command is constant, as (end, v, w) in turn
        (the first from t_a, each next from the previous end): split at the sorted, distinct
        transitions_between(t_a, t_b), with (v, w) = vw_at(start of the piece), the same
        floats; one call per span for the planner's predictions, with the entry in force
        carried along the (sorted) starts rather than looked up by a bisect per piece."""
        starts, t_hold, t_fail = self.starts, self.t_hold, self.t_fail
        if not starts:
            return [(t_b, self.idle_v, 0.0)]
        vs, ws = self.vs, self.ws
        n = len(starts)
        # the common span: within RUN throughout (neither HOLD nor FAILSAFE in (t_a, t_b))
        run = t_a < t_b <= t_hold and t_b <= t_fail
        if n == 1 and run:
            return [(t_b, vs[0], ws[0])]
        k = 0
        if n > 1:
            i = bisect_right(starts, t_a)
            k = i - 1 if i else 0  # vw_at(t_a)'s entry
            lo = i or 1  # entries 1..n only
            hi = bisect_left(starts, t_b, lo)
            if run:
                # cut at the starts in (t_a, t_b) alone (the common span): those are
                # sorted, so dropping repeats is what sorted(set(...)) did, and the entry in
                # force from a cut is the last one starting there
                out: list[tuple[float, float, float]] = []
                s = t_a
                for m in range(lo, hi):
                    c = starts[m]
                    if c != s:
                        out.append((c, vs[k], ws[k]))
                        s = c
                    k = m
                out.append((t_b, vs[k], ws[k]))
                return out
        # transitions_between's cuts, in its order
        cuts = [x for x in (t_hold, t_fail) if t_a < x < t_b]
        if n > 1:
            cuts.extend(starts[lo:hi])
        if len(cuts) > 1:
            cuts = sorted(set(cuts))
        cuts.append(t_b)
        out = []
        s = t_a
        for c in cuts:
            if s < t_hold:
                # the piece starts s only grow: the last entry started by s is found by
                # stepping on from the previous piece's (bisect_right - 1 on sorted starts)
                while k + 1 < n and starts[k + 1] <= s:
                    k += 1
                out.append((c, vs[k], ws[k]))
            else:
                out.append((c, self._held_v(s), 0.0))
            s = c
        return out

    @classmethod
    def of_command(
        cls,
        stamp: float,
        step_s: float,
        vs: Sequence[float],
        ws: Sequence[float],
        cfg: WatchdogConfig,
        v_min: float,
    ) -> Schedule:
        """The schedule of a command stamped `stamp` with entries (vs[k], ws[k]) every step_s
        (already within the eq. (11) bounds), under the watchdog settings cfg and the
        vehicle's least speed v_min (the HOLD floor is max(0, v_min))."""
        starts = tuple(stamp + k * step_s for k in range(len(vs)))
        return cls(
            starts=starts,
            vs=tuple(vs),
            ws=tuple(ws),
            t_hold=starts[-1] + cfg.hold_after_s,
            t_fail=starts[-1] + cfg.failsafe_after_s,
            decel=cfg.hold_decel_mps2 or math.inf,  # 0: at once
            v_floor=max(0.0, v_min),
        )
