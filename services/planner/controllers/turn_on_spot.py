"""Turning on the spot to a heading (v = 0), before a path that leaves contact sideways.

Used only when the vehicle touches an obstacle and its way out (escape.py) does not start
along its heading: with no reverse, any forward arc would first drive the hull deeper, and
eq. (11) allows a yaw rate at v = 0 (R_min, eqs. (19)-(20), bounds paths, not this turn).

Law: w = clamp(e / (2 tau), w_min, w_max), e = wrap(heading - theta). The vehicle's yaw rate
follows the command as a first-order lag of time constant tau (VehicleConfig.yaw_tau_s), so
unsaturated the error obeys tau e'' + e' + e / (2 tau) = 0: a damping ratio of 1 / sqrt(2)
whatever tau, which overshoots by 4 %. The turn is done within `DONE_RAD`; the path tracker
removes what is left.

The hull is a disc (eq. (12)), so turning in place cannot bring it nearer anything; turning
while still under way could (a turn of radius v / w toward the obstacle). So a vehicle that
still moves is first stopped straight (v = 0, w = 0, as on NO_PATH), and turns once below
`STILL_MPS`.
"""

from __future__ import annotations

from dataclasses import dataclass

from common.scalar import clamp, wrap_angle
from services.planner.controllers.base import Limits, Pose, predict_pose

DONE_RAD = 0.1  # ~6 degrees: what the tracker absorbs within R_min in well under a metre
STILL_MPS = 0.1  # below this speed the vehicle counts as stopped: it may turn in place


@dataclass(frozen=True, kw_only=True)
class TurnOnSpot:
    """Turns the vehicle to `heading` (rad) at v = 0; `command` returns None once it is done."""

    heading: float
    limits: Limits
    yaw_tau_s: float

    def command(self, pose: Pose, latency_s: float = 0.0) -> tuple[float, float] | None:
        """(0, w) while the (delay-compensated) heading is off by more than DONE_RAD; (0, 0)
        first while the vehicle still moves."""
        theta = predict_pose(pose, latency_s)[2] if latency_s > 0.0 else pose[2]
        e = wrap_angle(self.heading - theta)
        if abs(e) <= DONE_RAD:
            return None
        if abs(pose[3]) > STILL_MPS:
            return self.limits.saturate(0.0, 0.0)
        w = clamp(e / (2.0 * self.yaw_tau_s), self.limits.w_min, self.limits.w_max)
        return self.limits.saturate(0.0, w)
