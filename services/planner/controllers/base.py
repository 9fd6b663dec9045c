"""What the tracking controllers share: eq. (11) limits, pose prediction, path-frame errors."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Protocol

from common.config.vehicle import VehicleConfig
from common.scalar import clamp, wrap_angle
from services.planner.controllers.arc_reference import ArcLengthReference

Pose = tuple[float, float, float, float, float]  # x, y, theta, v, w (estimate or truth)


@dataclass(frozen=True, kw_only=True, slots=True)
class Limits:
    """eq. (11) bounds on (v, w) plus the minimum turning radius R_min of eq. (19)-(20)."""

    v_min: float
    v_max: float
    w_min: float
    w_max: float
    r_min: float

    @staticmethod
    def from_vehicle(cfg: VehicleConfig) -> Limits:
        return Limits(
            v_min=cfg.v_min_mps,
            v_max=cfg.v_max_mps,
            w_min=cfg.w_min_rps,
            w_max=cfg.w_max_rps,
            r_min=cfg.turn_radius_min_m,
        )

    def saturate(self, v: float, w: float) -> tuple[float, float]:
        """eq. (11): clamp v to [v_min, v_max] and w to [w_min, w_max]; NaN becomes a stop."""
        if not (math.isfinite(v) and math.isfinite(w)):
            return max(0.0, self.v_min), 0.0
        return clamp(v, self.v_min, self.v_max), clamp(w, self.w_min, self.w_max)


class Controller(Protocol):
    """A pure path-tracking controller: (time, pose, reference) -> saturated (v, w)."""

    name: str

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]: ...

    def reset(self) -> None: ...


def predict_pose(pose: Pose, horizon_s: float) -> Pose:
    """eq. (7) integrated exactly for a constant twist (v, w) over horizon_s (an arc).

    This is the delay compensation: the pose the vehicle will have when the command computed
    from this (horizon_s old) estimate takes effect.
    """
    x, y, th, v, w = pose
    if horizon_s <= 0.0:
        return pose
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


def path_errors(
    x: float, y: float, theta: float, ref: ArcLengthReference, s: float
) -> tuple[float, float]:
    """Serret-Frenet errors at arc length s: (e_y lateral, > 0 left of the path; e_theta)."""
    px, py = ref.point_at_s(s)
    hp = ref.heading_at_s(s)
    e_y = -math.sin(hp) * (x - px) + math.cos(hp) * (y - py)
    return e_y, wrap_angle(theta - hp)
