"""Path-tracking controllers: the NURBS tracker and the paper's two baselines, one speed profile."""

from services.planner.controllers.arc_reference import ArcLengthReference
from services.planner.controllers.backstepping import Backstepping
from services.planner.controllers.base import Controller, Limits, Pose, predict_pose
from services.planner.controllers.factory import make_controller
from services.planner.controllers.fuzzy_pid import ImmuneFuzzyPid
from services.planner.controllers.nurbs_tracker import NurbsTracker
from services.planner.controllers.shapes import Circle, Polyline, StraightLine
from services.planner.controllers.speed import SpeedProfile

__all__ = [
    "Backstepping",
    "Circle",
    "Controller",
    "ImmuneFuzzyPid",
    "Limits",
    "NurbsTracker",
    "Polyline",
    "Pose",
    "SpeedProfile",
    "ArcLengthReference",
    "StraightLine",
    "make_controller",
    "predict_pose",
]
