"""Path-tracking controllers: the NURBS tracker and the paper's two baselines, one speed profile."""

from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.backstepping import Backstepping
from services.control.controllers.base import Controller, Limits, Pose, predict_pose
from services.control.controllers.factory import make_controller
from services.control.controllers.fuzzy_pid import ImmuneFuzzyPid
from services.control.controllers.nurbs_tracker import NurbsTracker
from services.control.controllers.shapes import Circle, Polyline, StraightLine
from services.control.controllers.speed import SpeedProfile

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
