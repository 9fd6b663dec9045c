"""The simulated world: obstacles alpha_k(t) and the clearance of eq. (12)."""

from common.world.model import ObstacleState, World

__all__ = ["ObstacleState", "World"]
