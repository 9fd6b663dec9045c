"""Planner service: cost map, graph search, NURBS fit and refinement, replan policy, controllers.

Functional API of the planning pipeline (pure: no clock, no randomness, no I/O):

    result = plan_path(PlanRequest(start=..., goal=..., obstacles=...), PlannerConfig())
    if result.ok:
        path = PlannedPath(result.curve())  # arc length, projection, curvature for tracking
"""

from services.planner.geometry import (
    Area,
    Circle,
    MovingCircle,
    Obstacles,
    Polygon,
    Pose2D,
)
from services.planner.nurbs_curve import NurbsCurve
from services.planner.plan import PlanRequest, PlanResult, PlanTiming, plan_path
from services.planner.planned_path import PlannedPath
from services.planner.replan import ReplanDecision, ReplanPolicy, replan_request

__all__ = [
    "Area",
    "Circle",
    "MovingCircle",
    "NurbsCurve",
    "PlannedPath",
    "Obstacles",
    "PlanRequest",
    "PlanResult",
    "PlanTiming",
    "Polygon",
    "Pose2D",
    "ReplanDecision",
    "ReplanPolicy",
    "plan_path",
    "replan_request",
]
