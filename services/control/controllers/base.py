"""What the tracking controllers share: eq. (11) and R_min limits, pose prediction, path errors."""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any, Protocol

from common.config.vehicle import VehicleConfig
from common.scalar import clamp, wrap_angle
from services.control.controllers.arc_reference import ArcLengthReference

Pose = tuple[float, float, float, float, float]  # x, y, theta, v, w (estimate or truth)

# crab_angle: the largest heading offset into a current, and the least speed it assumes
MAX_CRAB_RAD = math.radians(45.0)
CRAB_MIN_SPEED_MPS = 0.5

# the types a copy of a controller's state shares with it (immutable; tuples of them too)
_IMMUTABLE = (float, int, bool, str, type(None))


@dataclass(frozen=True, kw_only=True, slots=True)
class Limits:
    """eq. (11) bounds on (v, w) plus the minimum turning radius R_min of eq. (19)-(20)."""

    v_min: float
    v_max: float
    w_min: float
    w_max: float
    r_min: float
    yaw_lead_s: float = 0.0  # how far ahead (s) a controller reads its reference (`ahead`)

    @staticmethod
    def from_vehicle(cfg: VehicleConfig, *, yaw_lag_lead: bool = False) -> Limits:
        """The vehicle's bounds; with `yaw_lag_lead` references are read its yaw_tau_s ahead."""
        return Limits(
            v_min=cfg.v_min_mps,
            v_max=cfg.v_max_mps,
            w_min=cfg.w_min_rps,
            w_max=cfg.w_max_rps,
            r_min=cfg.turn_radius_min_m,
            yaw_lead_s=cfg.yaw_tau_s if yaw_lag_lead else 0.0,
        )

    def ahead(self, s: float, v_now: float, length: float) -> float:
        """The arc length at which a controller reads its path reference for a vehicle at s
        moving at v_now: yaw_lead_s ahead (the plant's yaw rate follows its command with that
        time constant: a turn asked for where it begins is made late, and wide), at most the
        path's end (ControllerConfig.yaw_lag_lead)."""
        return min(s + max(v_now, 0.0) * self.yaw_lead_s, length) if self.yaw_lead_s else s

    def turn_cap(self, v_now: float) -> float:
        """The largest |w| (rad/s) a vehicle moving at v_now (m/s) can turn: v_now / R_min.

        The plant enforces it (services/vehicle/dynamics.py: eqs. (19)-(20) made physical),
        so every controller caps its yaw rate by the speed the vehicle has, not the speed it
        is asked for: accelerating from rest, a cap from the commanded speed asks for turns
        tighter than R_min that the vehicle cannot make.
        """
        return max(v_now, 0.0) / self.r_min if math.isfinite(v_now) else 0.0

    def saturate(self, v: float, w: float, v_now: float) -> tuple[float, float]:
        """eq. (11): clamp v to [v_min, v_max] and w to [w_min, w_max], and |w| to
        turn_cap(v_now) (R_min at the vehicle's speed v_now); NaN becomes a stop."""
        isfinite = math.isfinite
        if not (isfinite(v) and isfinite(w)):
            return max(0.0, self.v_min), 0.0
        # turn_cap and the clamps written out, the same floats (max(a, b) is b if b > a
        # else a, min(a, b) b if b < a else a): every entry of a command sequence ends here
        cap = (0.0 if 0.0 > v_now else v_now) / self.r_min if isfinite(v_now) else 0.0
        v_lo, v_hi = self.v_min, self.v_max
        w_lo = -cap if -cap > self.w_min else self.w_min
        w_hi = cap if cap < self.w_max else self.w_max
        return (
            v_lo if v < v_lo else v_hi if v > v_hi else v,
            w_lo if w < w_lo else w_hi if w > w_hi else w,
        )


class Controller(Protocol):
    """A path-tracking controller: (time, pose, reference) -> saturated (v, w).

    Its speed comes from the shared profile (speed.py) and its |w| is capped at the pose's
    speed over R_min (`Limits.saturate`): the controllers differ in how they steer only.
    """

    name: str
    current: tuple[float, float]  # the estimated current (m/s, world frame) it compensates
    sway: float  # the estimated sway of the hull (m/s, to port): its course is not its heading

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]: ...

    def reset(self) -> None: ...


def predict_pose(pose: Pose, horizon_s: float, current: tuple[float, float] = (0.0, 0.0)) -> Pose:
    """eq. (7) integrated exactly for a constant twist (v, w) over horizon_s (an arc; back
    along it for horizon_s < 0), carried by a constant current (cx, cy) (m/s, world frame).

    This is the delay compensation: the pose the vehicle will have when the command computed
    from this (horizon_s old) estimate takes effect.
    """
    x, y, th, v, w = pose
    if horizon_s == 0.0:
        return pose
    x += current[0] * horizon_s
    y += current[1] * horizon_s
    dth = w * horizon_s
    if abs(dth) < 1e-9:  # straight: avoid v/w with w -> 0
        return x + v * horizon_s * math.cos(th), y + v * horizon_s * math.sin(th), th, v, w
    r = v / w
    return (
        x + r * (math.sin(th + dth) - math.sin(th)),
        y - r * (math.cos(th + dth) - math.cos(th)),
        th + dth,
        v,
        w,
    )


def crab_angle(current: tuple[float, float], path_heading: float, v: float) -> float:
    """The heading offset beta (rad) that keeps a vehicle's velocity over ground along
    `path_heading` in a current (cx, cy): heading path_heading + beta at speed v through the
    water, v sin(beta) cancels the current's component across the path, c_n (> 0 to the
    left), so beta = -asin(c_n / v). The speed is taken as at least CRAB_MIN_SPEED_MPS and
    |beta| is at most MAX_CRAB_RAD: into a current that strong the vehicle can slow its drift,
    not stop it."""
    cx, cy = current
    if cx == 0.0 and cy == 0.0:
        return 0.0
    c_n = -math.sin(path_heading) * cx + math.cos(path_heading) * cy
    bound = math.sin(MAX_CRAB_RAD)
    return -math.asin(clamp(c_n / max(v, CRAB_MIN_SPEED_MPS), -bound, bound))


def path_errors(
    x: float, y: float, theta: float, ref: ArcLengthReference, s: float
) -> tuple[float, float]:
    """Serret-Frenet errors at arc length s: (e_y lateral, > 0 left of the path; e_theta)."""
    px, py = ref.point_at_s(s)
    hp = ref.heading_at_s(s)
    e_y = -math.sin(hp) * (x - px) + math.cos(hp) * (y - py)
    return e_y, wrap_angle(theta - hp)


def copied_state(state: dict[str, Any], memo: dict[int, Any]) -> dict[str, Any]:
    """The attributes `state` of an object for its deep copy (copy.deepcopy's `memo`): the
    immutable values and the tuples of them shared, the rest deep-copied. A command sequence
    rolls a copy of the controller out (sequence.py): its state is floats and tuples of
    floats, and deepcopy's dispatch on each of them was most of a copy's cost."""
    out: dict[str, Any] = {}
    for key, value in state.items():
        kind = type(value)
        if kind in _IMMUTABLE or (kind is tuple and all(type(e) in _IMMUTABLE for e in value)):
            out[key] = value
        else:
            out[key] = copy.deepcopy(value, memo)
    return out
