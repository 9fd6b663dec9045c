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

from common.config.scenario import Scenario
from common.messages import Message, TruthState
from common.world.current import CurrentField

# Consecutive truth states are one vehicle period apart; a realtime vehicle that fell behind
# skips whole periods. More than this between two of them is no continuous motion.
MAX_STEP_S = 1.0
# Margin on the distance: RK4 and the speed loop are not a straight line at constant speed.
REACH_FACTOR = 2.0
REACH_TOL_M = 0.01


def reach_mps(s: Scenario) -> float:
    """The fastest the vehicle moves over ground: v_max plus the world's current at its
    fastest (CurrentField.speed_bound_mps: flow, shear, tide, eddies, six standard
    deviations of the gusts on each axis)."""
    water = CurrentField(s.world.current, s.world.area, s.run.seed)
    return s.vehicle.v_max_mps + water.speed_bound_mps()


def follows(prev: Message | None, cur: TruthState, speed_mps: float) -> bool:
    """Whether `cur` can follow `prev` (the state recorded at cur.seq - 1) at `speed_mps`."""
    if not isinstance(prev, TruthState) or prev.seq != cur.seq - 1:
        return False
    dt = cur.stamp - prev.stamp
    if not 0.0 < dt <= MAX_STEP_S:
        return False
    moved = math.hypot(cur.x - prev.x, cur.y - prev.y)
    return moved <= REACH_FACTOR * speed_mps * dt + REACH_TOL_M
