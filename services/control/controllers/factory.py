"""Build the configured path-tracking controller."""

from __future__ import annotations

from common.config.controller import ControllerConfig
from services.control.controllers.backstepping import Backstepping
from services.control.controllers.base import Controller, Limits
from services.control.controllers.fuzzy_pid import ImmuneFuzzyPid
from services.control.controllers.nurbs_tracker import NurbsTracker


def make_controller(cfg: ControllerConfig, limits: Limits) -> Controller:
    """The controller `cfg.kind` names, with its gains; the speed profile and the delay
    compensation are the same for every controller."""
    if cfg.kind == "nurbs":
        return NurbsTracker(
            cfg.nurbs, limits, speed=cfg.speed, compensate_delay=cfg.delay_compensation
        )
    if cfg.kind == "backstepping":
        return Backstepping(
            cfg.backstepping, limits, speed=cfg.speed, compensate_delay=cfg.delay_compensation
        )
    return ImmuneFuzzyPid(
        cfg.fuzzy_pid, limits, speed=cfg.speed, compensate_delay=cfg.delay_compensation
    )
