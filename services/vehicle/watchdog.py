"""Command watchdog of a networked loop: reject stale or reordered commands, consume a
command's sequence of future entries, HOLD when it runs out, then FAILSAFE.

A command carries entries k = 0..n (n = 0: a single command): entry k, (v_k, w_k), is in
force from t_k = stamp + k * step_s (packet-based predictive control). Rules (times on the
runtime clock; t_last = t_n, the start of the last entry, = stamp for a single command):
- a command is rejected, and counted by reason, in this order: `too_long` if it carries
  more than max_sequence_len future entries (judged first, so a hostile length costs
  nothing); `non_finite` if any field is; `wrong_source` if it comes from another source
  than the vehicle's commander (the envelope's `source`, when a commander is set); `future`
  if stamped more than max_future_s ahead of t_now; `malformed` if its future speeds and
  rates differ in length or its step lies outside the wire's [1 ms, 10 s]; `too_long` if
  t_last - stamp > max_horizon_s; `out_of_order` if stamp < the stamp of the sequence in
  force (overtaken on the network: the newest sequence wins, whole); `stale` if
  t_now - t_last > max_command_age_s + d, with d >= 0 the median one-way delay measured on
  the commands *before* this one (delay.py). Staleness is age beyond the known delay, so a
  steady 1 s delay is not an outage, and a sequence stamped long ago still counts while its
  entries reach to about now; a command cannot vouch for its own delay. A duplicate (stamp
  equal to the one in force) is idempotent and re-applied. The future check comes before
  the order check, so no single command can lock out every later one;
- every command that passes the source, finiteness, future and shape checks is a delay
  sample (t_now - stamp), the late and overtaken ones included: their delay is real; a copy
  (the stamp of a recent sample again) is not (common/control/delay.py);
- an accepted command replaces the sequence in force from its delivery on; each entry is
  clamped to the eq. (11) bounds (counted once in `clamped` when any had to be), never
  applied raw. Its entries are applied in turn; the last one stays in force;
- HOLD counts from the end of the buffer, t_last, as it counted from a single command's
  stamp before sequences existed: from t_hold = t_last + hold_after_s the commanded speed
  falls to the floor (max(0, v_min)) at hold_decel_mps2 and the yaw rate is zero (heading
  hold): mode HOLD. The last entry is thus treated exactly as a single command stamped t_last
  (a single command behaves as it always did), and a sequence buys its whole horizon on top
  of hold_after_s of blind running. By default (hold_decel_mps2 = 0) the speed command drops
  at once and the speed loop brakes at the hull's limit, the shortest stop the plant allows
  (a blind vehicle should cover as little ground as it can; with v_min = 0 the distance is
  bounded, see WatchdogConfig);
- from t_fail = t_last + failsafe_after_s the mode is FAILSAFE (same motion) until a fresh
  command.
The command in force is kept as its Schedule (common/control/schedule.py), which the planner
uses too, to model what the vehicle applies from the commands it has sent.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Literal, get_args

from common.config.vehicle import WatchdogConfig
from common.control import Applied, DelayMeter, Schedule
from common.messages import SEQUENCE_STEP_MAX_MS, SEQUENCE_STEP_MIN_MS

Rejection = Literal[
    "non_finite", "wrong_source", "future", "malformed", "too_long", "out_of_order", "stale"
]
Verdict = Literal["applied", Rejection]
REJECTIONS: tuple[Rejection, ...] = get_args(Rejection)


class Watchdog:
    """Pure, stateful command filter; no clock of its own (every call passes the time)."""

    def __init__(
        self,
        cfg: WatchdogConfig,
        *,
        v_min: float,
        v_max: float,
        w_min: float,
        w_max: float,
        commander: str | None = None,
        idle_v: float = 0.0,
    ) -> None:
        self._cfg = cfg
        self._commander = commander  # the only source whose commands count (None: any)
        self._v_bounds = (v_min, v_max)
        self._w_bounds = (w_min, w_max)
        self.schedule = Schedule(idle_v=idle_v)  # a start under way holds its speed
        self.delay = DelayMeter(cfg.delay_window)
        self.applied = 0
        self.clamped = 0
        self._rejected: dict[str, int] = dict.fromkeys(REJECTIONS, 0)

    @property
    def rejected(self) -> int:
        """All rejected commands, whatever the reason."""
        return sum(self._rejected.values())

    @property
    def rejections(self) -> dict[str, int]:
        """Rejected commands by reason (every reason, zeros included; a copy)."""
        return dict(self._rejected)

    def offer(
        self,
        t_now: float,
        stamp: float,
        v: float,
        w: float,
        source: str = "",
        *,
        step_s: float = 0.0,
        v_next: Sequence[float] = (),
        w_next: Sequence[float] = (),
    ) -> Verdict:
        """Judge a command from `source` delivered at t_now: (v, w) from `stamp`, then
        (v_next[k-1], w_next[k-1]) from stamp + k * step_s; apply it (clamped) unless it is
        rejected (the verdict says why)."""
        verdict = self._judge(t_now, stamp, v, w, source, step_s, v_next, w_next)
        if verdict != "applied":
            self._rejected[verdict] += 1
            return verdict
        # eq. (11): clamp every entry to the bounds, and count that we had to
        v_all, w_all = (v, *v_next), (w, *w_next)
        vs = _clamped(v_all, *self._v_bounds)
        ws = _clamped(w_all, *self._w_bounds)
        if vs != v_all or ws != w_all:
            self.clamped += 1
        self.applied += 1
        self.schedule = Schedule.of_command(stamp, step_s, vs, ws, self._cfg, self._v_bounds[0])
        return "applied"

    def _judge(
        self,
        t_now: float,
        stamp: float,
        v: float,
        w: float,
        source: str,
        step_s: float,
        v_next: Sequence[float],
        w_next: Sequence[float],
    ) -> Verdict:
        """The verdict on a command, in the order of the module docstring; records its delay."""
        n = len(v_next)
        if max(n, len(w_next)) > self._cfg.max_sequence_len:
            return "too_long"
        isfinite = math.isfinite
        # each part in turn: no tuple of every entry built for it (a sequence has ~100)
        if not (
            all(map(isfinite, (stamp, v, w, step_s)))
            and all(map(isfinite, v_next))
            and all(map(isfinite, w_next))
        ):
            return "non_finite"
        if self._commander is not None and source != self._commander:
            return "wrong_source"
        if stamp - t_now > self._cfg.max_future_s:
            return "future"
        step_ok = SEQUENCE_STEP_MIN_MS <= step_s * 1000 <= SEQUENCE_STEP_MAX_MS
        if len(w_next) != n or (n and not step_ok):
            return "malformed"
        if n * step_s > self._cfg.max_horizon_s:
            return "too_long"
        allowance = max(0.0, self.delay.delay_s)  # from the commands before this one
        self.delay.add(t_now - stamp, stamp)
        last = self.schedule.stamp
        if last is not None and stamp < last:
            return "out_of_order"
        if t_now - (stamp + n * step_s) > self._cfg.max_command_age_s + allowance:
            return "stale"
        return "applied"

    def command(self, t: float) -> Applied:
        """The command in force at time t under the current schedule."""
        return self.schedule.at(t)


def _clamped(xs: Sequence[float], lo: float, hi: float) -> tuple[float, ...]:
    """min(max(x, lo), hi) of each x, written out (max(a, b) is b if b > a else a, min(a, b)
    b if b < a else a: the same floats) in one list comprehension: a generator of builtin
    calls over every entry of every command took 1.5 % of a mission, and a comprehension for
    each of max and min twice one."""
    # x below lo gives min(lo, hi) whatever x is (NaN is not below lo: it passes through)
    lo_hi = hi if hi < lo else lo
    return tuple([lo_hi if lo > x else hi if hi < x else x for x in xs])
