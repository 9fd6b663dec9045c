"""Whether a true state can follow the one before it: a run's judge believes only a vehicle
that got there by moving.

A record refuses messages from the wrong source or with an impossible seq, but a message
forged with the vehicle's name and a plausible seq could still claim the goal. The vehicle
publishes its truth every period, so its state at seq n follows the one at seq n - 1 within
a short time and within the distance it can travel in that time; a state that teleports there,
or whose predecessor is missing, does not end the mission or count as reaching the goal.
"""

from __future__ import annotations

import math

from common.config.vehicle import VehicleConfig
from common.messages import Message, TruthState

# Consecutive truth states are one vehicle period apart; a realtime vehicle that fell behind
# skips whole periods. More than this between two of them is no continuous motion.
MAX_STEP_S = 1.0
# Margin on the distance: RK4 and the speed loop are not a straight line at constant speed.
REACH_FACTOR = 2.0
REACH_TOL_M = 0.01


def reach_mps(cfg: VehicleConfig) -> float:
    """The fastest the vehicle moves over ground: v_max plus the current (its constant part
    and six standard deviations of the Gauss-Markov part on each axis)."""
    c = cfg.current
    return cfg.v_max_mps + math.hypot(c.x_mps, c.y_mps) + 6.0 * math.sqrt(2.0) * c.sigma_mps


def follows(prev: Message | None, cur: TruthState, speed_mps: float) -> bool:
    """Whether `cur` can follow `prev` (the state recorded at cur.seq - 1) at `speed_mps`."""
    if not isinstance(prev, TruthState) or prev.seq != cur.seq - 1:
        return False
    dt = cur.stamp - prev.stamp
    if not 0.0 < dt <= MAX_STEP_S:
        return False
    moved = math.hypot(cur.x - prev.x, cur.y - prev.y)
    return moved <= REACH_FACTOR * speed_mps * dt + REACH_TOL_M
