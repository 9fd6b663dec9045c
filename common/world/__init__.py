"""The one world model: obstacles alpha_k(t), their prediction, polygon geometry, eq. (12)."""

from common.world.model import ObstacleState, World

__all__ = ["ObstacleState", "World"]
