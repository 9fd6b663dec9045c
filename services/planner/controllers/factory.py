"""Build the configured path-tracking controller."""

from __future__ import annotations

from common.config.controller import ControllerConfig
from services.planner.controllers.backstepping import Backstepping
from services.planner.controllers.base import Controller, Limits
from services.planner.controllers.fuzzy_pid import ImmuneFuzzyPid
from services.planner.controllers.nurbs_tracker import NurbsTracker


def make_controller(cfg: ControllerConfig, limits: Limits) -> Controller:
    """The controller `cfg.kind` names, with its gains and delay-compensation setting.

    Delay compensation is on for the NURBS method when `delay_compensation`, and for the
    baselines only when `compensate_baselines` is also set.
    """
    baseline_comp = cfg.delay_compensation and cfg.compensate_baselines
    if cfg.kind == "nurbs":
        return NurbsTracker(cfg.nurbs, limits, compensate_delay=cfg.delay_compensation)
    if cfg.kind == "backstepping":
        return Backstepping(cfg.backstepping, limits, compensate_delay=baseline_comp)
    return ImmuneFuzzyPid(cfg.fuzzy_pid, limits, compensate_delay=baseline_comp)
