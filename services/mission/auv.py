"""AuvMission: the AUV dataflow of a scenario, when its run is over, and its metrics."""

from __future__ import annotations

import math
from typing import Any

from common.config.scenario import Scenario
from common.messages import TruthState
from common.runtime.model.record import Record
from common.world import World
from services.mission.continuity import follows, reach_mps
from services.mission.dataflow import auv_dataflow
from services.mission.metrics import mission_metrics
from services.mission.placed import placed


class AuvMission:
    """The mission of `[run] mission = "auv"` (the default)."""

    def __init__(self, scenario: Scenario) -> None:
        self.s = scenario
        self.max_time_s = scenario.run.max_time_s
        self.dataflow = placed(auv_dataflow(scenario), scenario.placement, scenario.network)
        self.world = World(scenario.world)
        self.reach_mps = reach_mps(scenario.vehicle)

    def observe(self, record: Record) -> str | None:
        """'goal' once the true vehicle is within the goal tolerance, judged on the vehicle's
        own truth stream (the record refuses another source and impossible seqs) and only by
        a state that follows its predecessor (services/mission/continuity.py)."""
        last = record.last("vehicle", "truth")
        if not isinstance(last, TruthState):
            return None
        g = self.s.world.goal
        if math.hypot(last.x - g.x_m, last.y - g.y_m) > self.s.world.goal_tolerance_m:
            return None
        if not follows(record.message("vehicle", "truth", last.seq - 1), last, self.reach_mps):
            return None
        return "goal"

    def metrics(self, record: Record) -> dict[str, Any]:
        return mission_metrics(record, self.s, self.world)
