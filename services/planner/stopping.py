"""Where a stopping vehicle stays: at the end of a way aside, or given way to the current."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from services.control.command.link import Hold, Prediction
from services.control.command.response import Pose
from services.planner.asking import PlanAsking
from services.planner.geometry.clearance import StaticField, current_pushes_clear
from services.planner.obstacle_picture import ObstaclePicture
from services.planner.result import PlanResult
from services.planner.shaping.path_arc_reference import PathArcReference

StopCommand = Callable[[Pose], tuple[float, float]]  # a stop's (v, w) for a pose

# a stop's station keeping is flown this long (s) before it is commanded (`Stopping.hold`):
# coming about from downstream at cruise speed on R_min takes about this long
COME_ABOUT_S = 12.0


class Stopping:
    """When the vehicle stops rather than follow its path (`run_out`), and how it then holds
    in a current (`hold`): keeping station, or letting the current carry it."""

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

    def hold(self, pred: Prediction) -> Hold:
        """How a stop holds (link.py `Hold`): it gives way to the current when an obstacle
        lies close upstream (`gives_way`); it drifts when keeping station, which comes about
        at cruise speed, would sweep the hull inside rho0 of a static obstacle within
        COME_ABOUT_S and drifting keeps it farther (ocean, fuzzy PID seed 1505: in NO_PATH,
        heading downstream 6 m short of obstacle 5, it came about into it, 17 s in contact)."""
        if self.gives_way(pred):
            return "give_way"
        link = self.asking.link
        keep = link.station_keeper()
        if keep is None:
            return "station"  # a stop is zeros either way
        rho0 = self.cfg.rho0_m
        kept = self._least_clearance(pred, keep)
        if kept >= rho0:
            return "station"
        drift = self._least_clearance(pred, lambda pose: (0.0, 0.0))
        return "drift" if drift > kept else "station"

    def _least_clearance(self, pred: Prediction, command: StopCommand) -> float:
        """The hull's least clearance from the static obstacles (m) over COME_ABOUT_S of a
        stop commanding `command(pose)` every control period, on the response model."""
        if self.static_field.empty:
            return np.inf
        link = self.asking.link
        pose, pts = pred.at_effect, []
        for _ in range(round(COME_ABOUT_S / link.step_s)):
            v, w = command(pose)
            pose = link.model.advance(pose, v, w, link.step_s)
            pts.append(pose[:2])
        d = self.static_field.distance(np.asarray(pts))[0]
        return float(d.min()) - self.vehicle.radius_m

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
