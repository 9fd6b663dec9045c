"""Command watchdog of a networked loop: reject stale or reordered commands, HOLD, FAILSAFE.

Rules (times on the runtime clock, `stamp` = the command's validity time):
- a command with a non-finite field, from another source than the vehicle's commander (the
  envelope's `source`, when a commander is set), stamped more than max_future_s ahead of
  t_now, with stamp < the last applied stamp (overtaken on the network), or with age
  t_now - stamp > max_command_age_s is rejected and counted by reason; a duplicate (stamp
  equal to the last applied one) is idempotent and re-applied. The future check comes
  before the order check, so no single command can lock out every later one;
- an accepted command is clamped to the eq. (11) bounds (counted in `clamped` when it had to
  be), never applied raw;
- once the applied command is hold_after_s old, the commanded speed falls to the floor
  (max(0, v_min)) at hold_decel_mps2 and the yaw rate is zero (heading hold): mode HOLD. By
  default (hold_decel_mps2 = 0) the speed command drops at once and the speed loop brakes at
  the hull's limit, the shortest stop the plant allows (a blind vehicle should cover as
  little ground as it can; with v_min = 0 the distance is bounded, see WatchdogConfig);
- once it is failsafe_after_s old, the mode is FAILSAFE (same motion) until a fresh command.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

from common.config.vehicle import WatchdogConfig
from common.messages import VehicleMode

Verdict = Literal["applied", "non_finite", "wrong_source", "future", "out_of_order", "stale"]
REJECTIONS: tuple[Verdict, ...] = ("non_finite", "wrong_source", "future", "out_of_order", "stale")


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

    Before any command: IDLE, (0, 0). Then RUN with (v, w) until t_hold, then HOLD: the speed
    command falls to v_floor at `decel` (inf: at once), w = 0 (FAILSAFE from t_fail). The
    plant integrator keeps these per time window, so a command's effect does not depend on
    when the plant happens to be integrated.
    """

    stamp: float | None = None
    v: float = 0.0
    w: float = 0.0
    t_hold: float = math.inf  # stamp + hold_after_s
    t_fail: float = math.inf  # stamp + failsafe_after_s
    decel: float = 0.0
    v_floor: float = 0.0

    def at(self, t: float) -> Applied:
        """The command in force at time t (held constant over an integration step from t)."""
        if self.stamp is None:
            return Applied(mode="IDLE", v=0.0, w=0.0, age_s=0.0)
        age = max(0.0, t - self.stamp)  # a stamp from the future (clock skew) counts as fresh
        if t < self.t_hold:
            return Applied(mode="RUN", v=self.v, w=self.w, age_s=age)
        # HOLD / FAILSAFE: lower the commanded speed, hold the heading (w = 0); an infinite
        # rate drops it at once (inf * 0 would be NaN at t_hold itself)
        drop = math.inf if math.isinf(self.decel) else self.decel * (t - self.t_hold)
        v = min(self.v, max(self.v_floor, self.v - drop))
        mode: VehicleMode = "FAILSAFE" if t >= self.t_fail else "HOLD"
        return Applied(mode=mode, v=v, w=0.0, age_s=age)

    @property
    def transitions(self) -> tuple[float, float]:
        """The times at which this schedule changes mode by itself."""
        return self.t_hold, self.t_fail


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
    ) -> None:
        self._cfg = cfg
        self._commander = commander  # the only source whose commands count (None: any)
        self._v_bounds = (v_min, v_max)
        self._w_bounds = (w_min, w_max)
        self.schedule = Schedule()
        self.applied = 0
        self.clamped = 0
        self.rejected_stale = 0
        self.rejected_out_of_order = 0
        self.rejected_non_finite = 0
        self.rejected_wrong_source = 0
        self.rejected_future = 0

    @property
    def rejected(self) -> int:
        """All rejected commands, whatever the reason."""
        return sum(self.rejections.values())

    @property
    def rejections(self) -> dict[str, int]:
        """Rejected commands by reason (every reason, zeros included)."""
        return {r: getattr(self, f"rejected_{r}") for r in REJECTIONS}

    def offer(self, t_now: float, stamp: float, v: float, w: float, source: str = "") -> Verdict:
        """Judge a command from `source` delivered at t_now; apply it (clamped) unless it is
        rejected (the verdict says why)."""
        if not (math.isfinite(stamp) and math.isfinite(v) and math.isfinite(w)):
            self.rejected_non_finite += 1
            return "non_finite"
        if self._commander is not None and source != self._commander:
            self.rejected_wrong_source += 1
            return "wrong_source"
        if stamp - t_now > self._cfg.max_future_s:
            self.rejected_future += 1
            return "future"
        last = self.schedule.stamp
        if last is not None and stamp < last:
            self.rejected_out_of_order += 1
            return "out_of_order"
        if t_now - stamp > self._cfg.max_command_age_s:
            self.rejected_stale += 1
            return "stale"
        # eq. (11): clamp to the bounds, and count that we had to
        vc = min(max(v, self._v_bounds[0]), self._v_bounds[1])
        wc = min(max(w, self._w_bounds[0]), self._w_bounds[1])
        if vc != v or wc != w:
            self.clamped += 1
        self.applied += 1
        self.schedule = Schedule(
            stamp=stamp,
            v=vc,
            w=wc,
            t_hold=stamp + self._cfg.hold_after_s,
            t_fail=stamp + self._cfg.failsafe_after_s,
            decel=self._cfg.hold_decel_mps2 or math.inf,  # 0: at once
            v_floor=max(0.0, self._v_bounds[0]),
        )
        return "applied"

    def command(self, t: float) -> Applied:
        """The command in force at time t under the current schedule."""
        return self.schedule.at(t)
