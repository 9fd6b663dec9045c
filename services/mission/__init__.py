"""The AUV mission: the dataflow of sensor, estimator, planner and vehicle, its end and metrics."""

from services.mission.auv import AuvMission

__all__ = ["AuvMission"]
