"""The step every path-tracking controller starts with: the pose predicted, then projected on s.

The three controllers share their speed profile (speed.py), their delay compensation (the
pose predicted forward by the latency with eq. (7), `predict_pose`), the projection of
that pose on the path, searched near the previous one so that a path coming back near
itself is not left for another leg, and the compensation of the current. They differ only
in how they steer.

In a current (cx, cy) the path is followed over ground, so each law steers the unicycle the
velocity over ground makes (`over_ground`): g = v e_theta + vs n_theta + c, its course
chi = atan2(g) as the heading and |g| = U as the speed. A law that drives the course onto the
path heads the vehicle into the current by the crab angle. Its yaw rate is a course rate,
and the hull turns only its own velocity through the water, v e_theta + vs n_theta (its sway
vs: a hull slips sideways in a turn, so its course differs from its heading even in still
water): chi' = w (v g . e_theta + vs g . n_theta) / U^2, so the yaw rate commanded is the
law's times U^2 / (v g . e_theta + vs g . n_theta) (`finish`; a following
current widens every turn over ground, a head current tightens it). The speed a law commands
stays a speed through the water (the profile's), and the turn it may ask for is capped at the
speed through the water over R_min, as the hull turns.
"""

from __future__ import annotations

import math
from typing import Any, Generic, TypeVar

from common.config.controller import SpeedConfig
from common.scalar import wrap_angle
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Limits, Pose, copied_state, predict_pose
from services.control.controllers.speed import SpeedProfile

# over_ground takes the vehicle as moving at least this fast through the water (m/s): at
# rest its course would be the current's, whichever way it heads
STEERAGE_MPS = 0.5
# the course-rate-to-yaw-rate gain is kept within these bounds
COURSE_GAIN_MIN, COURSE_GAIN_MAX = 0.5, 2.0

G = TypeVar("G")


def _ground_velocity(
    v: float, c: float, sn: float, sway: float, cx: float, cy: float
) -> tuple[float, float]:
    """The velocity over ground (m/s, world) of a hull heading (c, sn) = (cos, sin) at v
    through the water, slipping `sway` to port, in the current (cx, cy)."""
    return v * c - sway * sn + cx, v * sn + sway * c + cy


def course_over_ground(theta: float, v: float, sway: float, current: tuple[float, float]) -> float:
    """The course over ground (rad) that PathFollower.over_ground steers for a hull heading
    theta at v through the water (at least STEERAGE_MPS), slipping `sway` to port, in
    `current`: the heading a path taken now must leave along, as the controllers see it.
    Exactly theta in still water with no sway."""
    cx, cy = current
    if cx == 0.0 and cy == 0.0 and sway == 0.0:
        return theta
    ve = max(v, STEERAGE_MPS)
    gx, gy = _ground_velocity(ve, math.cos(theta), math.sin(theta), sway, cx, cy)
    return theta + wrap_angle(math.atan2(gy, gx) - theta)


class PathFollower(Generic[G]):
    """Gains of type G, eq. (11) limits, the shared speed profile and the projection on s."""

    def __init__(
        self,
        gains: G,
        limits: Limits,
        *,
        speed: SpeedConfig | None = None,
        compensate_delay: bool = True,
    ) -> None:
        self.gains = gains
        self.limits = limits
        self.compensate_delay = compensate_delay
        self.speed = SpeedProfile(speed or SpeedConfig(), limits)
        self.current: tuple[float, float] = (0.0, 0.0)  # the estimated current (m/s, world)
        self.sway = 0.0  # the estimated sway (m/s, to port): the hull slips sideways in a turn
        self.water_speed = 0.0  # the projected pose's speed through the water (m/s)
        self._course_gain = 1.0  # yaw rate per course rate at the projected pose
        self.reset()

    def __deepcopy__(self, memo: dict[int, Any]) -> PathFollower[G]:
        """A copy with a state of its own (a command sequence rolls one out, sequence.py),
        sharing the frozen gains, limits and speed configuration: the default deepcopy
        rebuilt each of them, for every sequence, at two thirds of its cost."""
        for frozen in (self.gains, self.limits, self.speed.cfg):
            memo.setdefault(id(frozen), frozen)
        twin = type(self).__new__(type(self))
        memo[id(self)] = twin
        twin.__dict__.update(copied_state(self.__dict__, memo))
        return twin

    def reset(self) -> None:
        """Forget the path followed: the speed ramps from the vehicle's own speed again and
        the projection searches the whole path."""
        self.speed.reset()
        self._s_hint: float | None = None

    def project(self, pose: Pose, ref: ArcLengthReference, latency_s: float) -> tuple[Pose, float]:
        """The pose the command acts on (predicted by latency_s when compensating the delay;
        in a current, over ground: `over_ground`) and its arc length on `ref`, near the last
        one."""
        if self.compensate_delay and latency_s > 0.0:
            pose = predict_pose(pose, latency_s, self.current)
        s = ref.closest_s(pose[0], pose[1], self._s_hint)
        self._s_hint = s
        self.water_speed = pose[3]
        self._course_gain = 1.0
        if self.current != (0.0, 0.0) or self.sway != 0.0:
            pose = self.over_ground(pose)
        return pose, s

    def over_ground(self, pose: Pose) -> Pose:
        """(x, y, chi, U, w / gain): the unicycle of the velocity over ground (module
        docstring), the speed through the water taken as at least STEERAGE_MPS, the hull's
        sway included (a hull slips sideways in a turn: its course is not its heading); sets
        the gain `finish` turns a course rate into a yaw rate with."""
        x, y, th, v, w = pose
        ve = STEERAGE_MPS if STEERAGE_MPS > v else v  # max(v, STEERAGE_MPS)
        cx, cy = self.current
        c, sn = math.cos(th), math.sin(th)
        gx, gy = _ground_velocity(ve, c, sn, self.sway, cx, cy)
        u = math.hypot(gx, gy)
        along = ve + cx * c + cy * sn  # g . e_theta
        across = self.sway - cx * sn + cy * c  # g . n_theta
        turned = ve * along + self.sway * across  # chi' = w turned / U^2
        gain = u * u / turned if turned > 0.0 else COURSE_GAIN_MAX
        # clamp(gain, COURSE_GAIN_MIN, COURSE_GAIN_MAX) written out (a rollout asks this at
        # every entry)
        self._course_gain = (
            COURSE_GAIN_MIN
            if gain < COURSE_GAIN_MIN
            else COURSE_GAIN_MAX
            if gain > COURSE_GAIN_MAX
            else gain
        )
        chi = th + wrap_angle(math.atan2(gy, gx) - th)
        return x, y, chi, u, w / self._course_gain

    @property
    def current_speed(self) -> float:
        """The estimated current's speed (m/s)."""
        return math.hypot(*self.current)

    def ground_speed(self, v: float, heading: float) -> float:
        """The speed over ground (m/s) of a vehicle moving at v through the water whose
        velocity over ground lies along `heading` (crabbing into the current)."""
        cx, cy = self.current
        if cx == 0.0 and cy == 0.0:
            return v
        c, sn = math.cos(heading), math.sin(heading)
        c_n = -sn * cx + c * cy  # across the heading: the crab angle cancels it
        across = min(abs(c_n), v)
        return max(0.0, math.sqrt(v * v - across * across) + c * cx + sn * cy)

    def finish(self, v: float, w_course: float) -> tuple[float, float]:
        """A law's (speed through the water, course rate) as the command: the yaw rate that
        turns the course so, saturated to eq. (11) and |w| <= v / R_min at the speed through
        the water."""
        return self.limits.saturate(v, w_course * self._course_gain, self.water_speed)

    def course_rate(self, w: float) -> float:
        """The course rate a yaw rate from `finish` makes (the law's units)."""
        return w / self._course_gain
