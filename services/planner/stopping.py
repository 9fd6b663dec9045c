"""Where a stopping vehicle stays: at the end of a way aside, or given way to the current."""

from __future__ import annotations

from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from services.control.command.link import Prediction
from services.planner.asking import PlanAsking
from services.planner.geometry.clearance import StaticField, current_pushes_clear
from services.planner.obstacle_picture import ObstaclePicture
from services.planner.result import PlanResult
from services.planner.shaping.path_arc_reference import PathArcReference


class Stopping:
    """When the vehicle stops rather than follow its path (`run_out`), and whether it then
    keeps station or lets the current carry it back (`gives_way`)."""

    def __init__(
        self,
        cfg: PlannerConfig,
        vehicle: VehicleConfig,
        world: WorldConfig,
        seen: ObstaclePicture,
        asking: PlanAsking,
    ) -> None:
        self.cfg, self.vehicle, self.seen, self.asking = cfg, vehicle, seen, asking
        self.static_field = StaticField.build(world.circles, world.polygons)

    def run_out(
        self, pred: Prediction, ref: PathArcReference | None, last: PlanResult | None
    ) -> bool:
        """Has the vehicle (predicted: `pred`) reached the end of `ref`, the path of the plan
        `last`, short of the goal (a way aside, or partway)? Then it stops (keeps station)
        there until a plan is made: its speed profile keeps steerage in a current, which past
        the end would go on straight."""
        if ref is None or last is None or not last.short_of_goal:
            return False
        s_here = ref.closest_s(pred.at_effect[0], pred.at_effect[1], None)
        return ref.length - s_here <= self.cfg.tuning.arrived_m

    def gives_way(self, pred: Prediction) -> bool:
        """Should a stop let the current carry the vehicle back, rather than keep station at
        an obstacle close upstream (within rho0 and the margin of its hull)?"""
        x, y = pred.at_effect[0], pred.at_effect[1]
        keep_m = self.vehicle.radius_m + self.cfg.rho0_m + self.asking.clearance_margin_m
        # and room to turn away within R_min: held nearer, no plan can leave (a dead end)
        keep_m += self.cfg.tuning.give_way_room_r * self.vehicle.turn_radius_min_m
        moving = self.seen.at(pred.effect_t).moving
        current = self.asking.link.model.current_mps
        return current_pushes_clear(x, y, self.static_field, moving, current, keep_m)
