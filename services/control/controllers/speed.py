"""The speed profile every tracking controller follows: cruise cap, one ramp, the slow-downs.

Speed is shared so that the three controllers differ only in how they steer: a travel time
or a control count then measures steering, not a speed policy of each controller's own (the
baselines' literature has none to offer: Kanayama's law takes the reference speed v_r as
given, and the immune fuzzy PID steers only).

The target at arc length s (the vehicle's projection on the path, L the path's length):

    v_target(s) = min(v_cruise, v_curv(s), v_stop(s))
    v_cruise    = v_ref within eq. (11)
    v_curv(s)   = budget * w_max / max |kappa(s')|,  s' in [s, s + v_cruise * preview_s]
    v_stop(s)   = sqrt(2 decel (L - s))   (L: the path's end, or a stop short of it)

v_curv keeps the curvature feed-forward v |kappa| within `budget` of eq. (11)'s yaw-rate
bound over the preview window, leaving the rest to the feedback; v_stop brakes to a stop at
the end of the path at a constant deceleration, or sooner where the reference says so
(`stop_s`: the planner's path found unsafe ahead while its replacement is being made).

The command follows the target through one ramp: v_k = min(v_target, v_{k-1} + accel dt),
starting from the vehicle's own speed when a path is taken (`reset`, then the first
command), or carrying on from the last command if that is at least as fast and at most
ramp_carry_s old (a path taken while accelerating). Decreases are not rate-limited: the
preview and the stop anticipate them, and the hull brakes within its own acceleration bound.
"""

from __future__ import annotations

import math
from typing import Any

from common.config.controller import SpeedConfig
from common.scalar import clamp
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Limits, copied_state

_PREVIEW_SAMPLES = 7  # curvature samples over the preview window (incl. both ends)
_PREVIEW_STEPS = tuple(range(_PREVIEW_SAMPLES))


def cruise_speed(ref: ArcLengthReference, limits: Limits) -> float:
    """The cruise cap: the path's v_ref within eq. (11) (m/s)."""
    return clamp(ref.v_ref, limits.v_min, limits.v_max)


def stop_of(ref: ArcLengthReference) -> float:
    """Where the speed profile brings the vehicle to rest on `ref` (m of arc length): its end,
    or sooner where the reference says so (the planner's path found unsafe ahead)."""
    return float(getattr(ref, "stop_s", ref.length))


def target_speed(
    ref: ArcLengthReference, s: float, cfg: SpeedConfig, limits: Limits, current_mps: float = 0.0
) -> float:
    """v_target(s) of the module docstring (m/s), before the ramp; in a current of
    `current_mps` the stop at the path's end keeps steerage_per_current times it."""
    return _target(ref, s, cfg, limits, curvature_room(cfg, limits), current_mps)


def curvature_room(cfg: SpeedConfig, limits: Limits) -> float:
    """The yaw rate the curvature feed-forward may take (rad/s): budget * min(w_max, -w_min)."""
    return cfg.curvature_budget * min(limits.w_max, -limits.w_min)


def _target(
    ref: ArcLengthReference,
    s: float,
    cfg: SpeedConfig,
    limits: Limits,
    w_room: float,
    current_mps: float,
) -> float:
    """target_speed with its yaw-rate room given (SpeedProfile keeps it: a rollout asks this
    at every entry, so its lookups are each made once)."""
    v_min, v_max = limits.v_min, limits.v_max
    v = ref.v_ref
    v = v_min if v < v_min else v_max if v > v_max else v  # cruise_speed, written out
    length = ref.length
    horizon = s + v * cfg.preview_s
    horizon = horizon if horizon < length else length  # min(length, ...)
    # a reference that bounds its curvature over a stretch (the planner's path) lets the
    # samples be skipped where even the bound leaves v_curv above v: the same v, at a
    # fraction of the cost on straights and gentle curves (the rollout of a command sequence
    # asks this at every entry); and one that bounds it over the whole path (curvature_max)
    # lets the stretch's bound be skipped where even the path's leaves v_curv above v: on
    # most paths everywhere, one number read instead of a range query per entry
    k_path = getattr(ref, "curvature_max", None)
    bound = getattr(ref, "curvature_bound", None)
    if (k_path is None or k_path * v > w_room) and (
        bound is None or bound(s, horizon) * v > w_room
    ):
        curvature_at_s, span = ref.curvature_at_s, horizon - s
        k_max = 0.0
        for i in _PREVIEW_STEPS:
            k = abs(curvature_at_s(s + span * i / (_PREVIEW_SAMPLES - 1)))
            if k > k_max:
                k_max = k
        if k_max * v > w_room:
            v = w_room / k_max
    stop = float(getattr(ref, "stop_s", length))  # stop_of
    left = stop - s
    v_stop = math.sqrt(2.0 * cfg.decel_mps2 * (0.0 if 0.0 > left else left))
    if current_mps > 0.0 and stop >= length:  # not a stop short of a conflict
        v_stop = max(v_stop, cfg.steerage_per_current * current_mps)
    v = v_stop if v_stop < v else v  # min(v, v_stop)
    return v_min if v < v_min else v_max if v > v_max else v  # clamp, written out


class SpeedProfile:
    """The ramped speed command along one path: `reset` when a path is taken, then `command`."""

    def __init__(self, cfg: SpeedConfig, limits: Limits) -> None:
        self.cfg = cfg
        self.limits = limits
        self._w_room = curvature_room(cfg, limits)
        self._v: float | None = None  # the last command; None: ramp from the vehicle's speed
        self._t = 0.0  # ... and its time (s)
        # the last command before the last reset, and its time (None: none yet)
        self._carried: tuple[float, float] | None = None
        self.reset()

    def __deepcopy__(self, memo: dict[int, Any]) -> SpeedProfile:
        """A copy with a ramp of its own, sharing the frozen configuration and limits (a
        command sequence copies the controller it rolls out: PathFollower.__deepcopy__)."""
        for frozen in (self.cfg, self.limits):
            memo.setdefault(id(frozen), frozen)
        twin = SpeedProfile.__new__(SpeedProfile)
        memo[id(self)] = twin
        twin.__dict__.update(copied_state(self.__dict__, memo))
        return twin

    def reset(self) -> None:
        """A path is taken: the ramp starts afresh from the vehicle's speed, or carries on
        from the last command if that was at most cfg.ramp_carry_s ago (`command`)."""
        if self._v is not None:
            self._carried = (self._v, self._t)
        self._v = None  # the last command; None: ramp from the vehicle's speed
        self._t = 0.0

    def command(
        self, t: float, ref: ArcLengthReference, s: float, v_now: float, current_mps: float = 0.0
    ) -> float:
        """The speed to command at time t (s) for a vehicle at arc length s moving at v_now,
        in a current of current_mps."""
        target = _target(ref, s, self.cfg, self.limits, self._w_room, current_mps)
        # max, min and clamp written out (the same floats: max(a, b) is b if b > a else a)
        if self._v is None:
            # a path taken under way does not restart from rest
            base = 0.0 if 0.0 > v_now else v_now  # max(v_now, 0.0)
            carried = self._carried
            if carried is not None and 0.0 <= t - carried[1] <= self.cfg.ramp_carry_s:
                # nor from behind its own ramp: the hull's speed lags the command by the speed
                # loop's time constant, and restarting from it at every replan while
                # accelerating (a current's estimate settling asks one a second) left the
                # vehicle at 0.16 m/s 4 s after its start, drifting with a 0.3 m/s current
                # past the turn its path asked for
                v_ramp = carried[0] + self.cfg.accel_mps2 * (t - carried[1])
                base = v_ramp if v_ramp > base else base
        else:
            dt = t - self._t
            base = self._v + self.cfg.accel_mps2 * (dt if dt > 0.0 else 0.0)
        v = base if base < target else target
        lo, hi = self.limits.v_min, self.limits.v_max
        v = lo if v < lo else hi if v > hi else v
        self._v, self._t = v, t
        return v
