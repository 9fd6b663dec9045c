"""Planner service: cost map, graph search, NURBS fit and refinement, replan policy, controllers.

Functional API of the planning pipeline (pure: no clock, no randomness, no I/O):

    req = PlanRequest(start=..., goal=..., obstacles=..., vehicle_radius_m=vehicle.radius_m)
    result = plan_path(req, PlannerConfig())
    if result.ok:
        path = PlannedPath(result.curve())  # on the curve parameter u, with s(u) and u(s)
        ref = PathArcReference(path, v_ref)  # on arc length s: what a controller follows

Obstacles use the world's types (common.config.world circles and polygons, common.world's
ObstacleState for moving ones); the area is the scenario's AreaConfig.
"""

from services.planner.nurbs_curve import NurbsCurve
from services.planner.path_arc_reference import PathArcReference
from services.planner.plan import PlanRequest, PlanResult, PlanTiming, plan_path
from services.planner.planned_path import PlannedPath
from services.planner.replan import ReplanDecision, ReplanPolicy, replan_request
from services.planner.result import Obstacles, Pose2D

__all__ = [
    "NurbsCurve",
    "Obstacles",
    "PathArcReference",
    "PlanRequest",
    "PlanResult",
    "PlanTiming",
    "PlannedPath",
    "Pose2D",
    "ReplanDecision",
    "ReplanPolicy",
    "plan_path",
    "replan_request",
]
