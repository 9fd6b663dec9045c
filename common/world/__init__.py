"""The one world model: obstacles alpha_k(t), their prediction, polygon geometry, eq. (12), and
the ocean current every vehicle moves in (current.py)."""

from common.world.current import CurrentField
from common.world.model import ObstacleState, World

__all__ = ["CurrentField", "ObstacleState", "World"]
