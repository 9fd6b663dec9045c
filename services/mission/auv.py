"""AuvMission: builds the four service cores from a scenario and judges when the run is over."""

from __future__ import annotations

import hashlib
import math
from typing import Any

import numpy as np

from common.config.network import link_name, profile_for
from common.config.scenario import Scenario
from common.messages import TruthState
from common.runtime.core import ServiceCore
from common.runtime.record import Record
from common.world import World
from services.estimator.core import EstimatorCore
from services.mission.metrics import mission_metrics
from services.planner.core import PlannerCore
from services.sensor.core import SensorCore
from services.vehicle.core import VehicleCore


def core_rng(seed: int, service: str) -> np.random.Generator:
    """Each core's own generator, keyed by (seed, service name): independent and reproducible."""
    h = int.from_bytes(hashlib.blake2b(service.encode(), digest_size=8).digest(), "little")
    return np.random.default_rng([seed, h])


class AuvMission:
    """sensor -> estimator -> planner (+controller) -> vehicle -> (truth) -> sensor."""

    names = ("estimator", "planner", "sensor", "vehicle")

    def __init__(self, scenario: Scenario) -> None:
        self.s = scenario
        self.max_time_s = scenario.run.max_time_s
        self.world = World(scenario.world)
        self._truth_seen = 0

    def make_core(self, name: str) -> ServiceCore:
        s, seed = self.s, self.s.run.seed
        start = (s.world.start.x_m, s.world.start.y_m, s.world.start.theta_rad)
        if name == "vehicle":
            r = s.vehicle.radius_m
            return VehicleCore(
                s.vehicle,
                start,
                core_rng(seed, name),
                clearance=lambda x, y, t: self.world.clearance(x, y, r, t),
            )
        if name == "sensor":
            return SensorCore(s.sensor, self.world, core_rng(seed, name))
        if name == "estimator":
            return EstimatorCore(s.estimator, start, core_rng(seed, name))
        if name == "planner":
            down = profile_for(s.network, link_name("planner", "cmd", "vehicle"))
            return PlannerCore(
                s.planner, s.controller, s.vehicle, s.world, expected_downlink_s=down.delay_s
            )
        raise ValueError(f"unknown service {name!r}; this mission has {', '.join(self.names)}")

    def observe(self, record: Record) -> str | None:
        """'goal' once the true vehicle is within the goal tolerance."""
        last = record.last("vehicle", "truth")
        if not isinstance(last, TruthState):
            return None
        g = self.s.world.goal
        if math.hypot(last.x - g.x_m, last.y - g.y_m) <= self.s.world.goal_tolerance_m:
            return "goal"
        return None

    def metrics(self, record: Record) -> dict[str, Any]:
        return mission_metrics(record, self.s, self.world)
