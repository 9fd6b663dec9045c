"""AuvMission: the AUV dataflow of a scenario, when its run is over, and its metrics."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

from common.config.scenario import Scenario
from common.messages import TruthState
from common.runtime.model.dataflow import qualified
from common.runtime.model.record import Record
from common.world import World
from services.mission.continuity import follows, reach_mps
from services.mission.dataflow import auv_dataflow
from services.mission.fleet import fleet_dataflow
from services.mission.placed import placed

if TYPE_CHECKING:
    from services.mission.records import MissionMetrics


class AuvMission:
    """The mission of `[run] mission = "auv"` (the default)."""

    def __init__(self, scenario: Scenario) -> None:
        self.s = scenario
        self.max_time_s = scenario.run.max_time_s
        if scenario.vehicles:  # a fleet: services/mission/fleet.py
            self.dataflow = fleet_dataflow(scenario)
            self._vehicles = {qualified(vid, "vehicle"): m for vid, m in scenario.members}
        else:
            self.dataflow = placed(auv_dataflow(scenario), scenario.placement, scenario.network)
            self._vehicles = {"vehicle": scenario}
        self.world = World(scenario.world)
        self._arrived: set[str] = set()

    def observe(self, record: Record) -> str | None:
        """'goal' once every true vehicle has been within its goal tolerance, judged on each
        vehicle's own truth stream (the record refuses another source and impossible seqs) and
        only by a state that follows its predecessor (services/mission/continuity.py)."""
        for name, s in self._vehicles.items():
            if name not in self._arrived and _at_goal(record, name, s):
                self._arrived.add(name)
        return "goal" if len(self._arrived) == len(self._vehicles) else None

    def ends_on(self, service: str, stream: str) -> bool:
        """The end is judged on the vehicles' truth streams alone."""
        return stream == "truth" and service in self._vehicles

    def metrics(self, record: Record) -> MissionMetrics:
        """One vehicle's metrics (AuvMetrics), or a fleet's (FleetMetrics)."""
        # imported here: only a run's driver computes metrics, and they need the planner's
        # curves, which a service process would otherwise load for nothing
        from services.mission.fleet_metrics import fleet_metrics
        from services.mission.metrics import mission_metrics

        if self.s.vehicles:
            return fleet_metrics(record, self.s)
        return mission_metrics(record, self.s, self.world)


def _at_goal(record: Record, vehicle: str, s: Scenario) -> bool:
    """Is the newest truth of service `vehicle` within its goal tolerance, and plausible?"""
    last = record.last(vehicle, "truth")
    if not isinstance(last, TruthState):
        return False
    g = s.world.goal
    if math.hypot(last.x - g.x_m, last.y - g.y_m) > s.world.goal_tolerance_m:
        return False
    return follows(record.message(vehicle, "truth", last.seq - 1), last, reach_mps(s))
