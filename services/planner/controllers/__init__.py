"""Path-tracking controllers: the NURBS tracker (the paper's method) and its two baselines."""

from services.planner.controllers.backstepping import Backstepping
from services.planner.controllers.base import Controller, Limits, Pose, predict_pose
from services.planner.controllers.factory import make_controller
from services.planner.controllers.fuzzy_pid import ImmuneFuzzyPid
from services.planner.controllers.nurbs import NurbsTracker
from services.planner.controllers.reference import Reference
from services.planner.controllers.shapes import Circle, Polyline, StraightLine

__all__ = [
    "Backstepping",
    "Circle",
    "Controller",
    "ImmuneFuzzyPid",
    "Limits",
    "NurbsTracker",
    "Polyline",
    "Pose",
    "Reference",
    "StraightLine",
    "make_controller",
    "predict_pose",
]
