"""The step every path-tracking controller starts with: the pose predicted, then projected on s.

The three controllers share their speed profile (speed.py), their delay compensation (the
pose predicted forward by the latency with eq. (7), `predict_pose`) and the projection of
that pose on the path, searched near the previous one so that a path coming back near
itself is not left for another leg. They differ only in how they steer.
"""

from __future__ import annotations

from typing import Generic, TypeVar

from common.config.controller import SpeedConfig
from services.planner.controllers.arc_reference import ArcLengthReference
from services.planner.controllers.base import Limits, Pose, predict_pose
from services.planner.controllers.speed import SpeedProfile

G = TypeVar("G")


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
        self.reset()

    def reset(self) -> None:
        """Forget the path followed: the speed ramps from the vehicle's own speed again and
        the projection searches the whole path."""
        self.speed.reset()
        self._s_hint: float | None = None

    def project(self, pose: Pose, ref: ArcLengthReference, latency_s: float) -> tuple[Pose, float]:
        """The pose the command acts on (predicted by latency_s when compensating the delay)
        and its arc length on `ref`, near the last one."""
        if self.compensate_delay and latency_s > 0.0:
            pose = predict_pose(pose, latency_s)
        s = ref.closest_s(pose[0], pose[1], self._s_hint)
        self._s_hint = s
        return pose, s
