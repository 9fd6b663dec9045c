"""The tracker core: follows the newest path the planner sent with the chosen controller, onboard.

With ``controller.placement = "onboard"`` the planner (maybe at a topside station, across a
thin acoustic link) sends paths only, and this core, on the vehicle's node, computes the
commands from the onboard estimate: the same controller, speed profile, prediction, command
sequences and input checks as the planner's own (services/control/command/: link.py
`CommandLink.follow`, inputs.py), on a link that is local. A late or lost path costs
nothing but freshness: the tracker keeps following the last one it holds.
"""

from __future__ import annotations

import logging
import math

from common.config.controller import ControllerConfig
from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from common.guard import first_reason
from common.messages import PathMsg
from common.runtime.model.core import Delivery, Emit
from services.control.command.arrival import Arrival
from services.control.command.inputs import LoopInputs
from services.control.command.link import CommandLink
from services.control.controllers.base import Limits
from services.control.controllers.factory import make_controller
from services.planner.shaping.path_arc_reference import PathArcReference
from services.planner.shaping.planned_path import PlannedPath, curve_of

log = logging.getLogger("tidelink.tracker")


class TrackerCore:
    """Consumes estimator/state, planner/path and vehicle/status; publishes cmd."""

    def __init__(
        self,
        planner: PlannerConfig,
        controller: ControllerConfig,
        vehicle: VehicleConfig,
        world: WorldConfig,
    ) -> None:
        self.period_s = planner.period_s
        self.kind = controller.kind
        self.world = world
        self.link = CommandLink(planner, controller, vehicle, start_speed_mps=world.start.speed_mps)
        self.controller = make_controller(
            controller, Limits.from_vehicle(vehicle, yaw_lag_lead=controller.yaw_lag_lead)
        )
        self.inputs = LoopInputs(world.area, self.link, log)
        self.ref: PathArcReference | None = None
        self.path_id = 0  # of the path followed (0: none yet)
        g = world.goal
        self.arrival = Arrival((g.x_m, g.y_m), world.goal_tolerance_m)
        self.stale_skips = 0
        self.last_cmd_t: float | None = None

    @property
    def inputs_rejected(self) -> dict[str, int]:
        """Inputs rejected, by '<stream>.<reason>'."""
        return self.inputs.rejected

    def deliver(self, d: Delivery) -> list[Emit]:
        """Keep the newest estimate (by stamp) and the newest path (by path_id); implausible
        inputs are rejected, counted and logged, as the planner does."""
        msg = d.msg
        if isinstance(msg, PathMsg):
            why = first_reason(self.inputs.judge.stamp(msg.stamp, d.t))
            if why is not None:
                self.inputs.reject("path", why, d.t, msg)
            elif msg.path_id > self.path_id:
                self._take(msg)
        else:
            self.inputs.offer(d.t, msg)
        return []

    def _take(self, p: PathMsg) -> None:
        """Follow path `p` from now on (a NO_PATH stops the vehicle)."""
        self.path_id = p.path_id
        if p.status != "OK":
            self.ref = None
            return
        try:
            curve = curve_of(p)
        except ValueError as exc:  # well-formed on the wire, but no curve: keep stopping
            self.inputs.rejects.warn(
                "path.curve", p.stamp, "path %d has no curve: %s", p.path_id, exc
            )
            self.ref = None
            return
        self.ref = PathArcReference(PlannedPath(curve), p.v_ref)
        self.link.restart(self.controller)

    def prepare(self, t_next: float) -> None:
        """Once this step's command is out: the sequence for the step at t_next (command/link)."""
        if self.ref is not None and not self.arrival.arrived:
            self.link.prepare(t_next, self.controller, self.ref)

    def step(self, t: float) -> list[Emit]:
        if self.inputs.state is None:
            return []
        s = self.inputs.state
        arrived = self.arrival.update(s.x, s.y)
        if self.link.stale(t, s):
            self.stale_skips += 1
            return []
        pred = self.link.predict(t, s)
        gap = math.inf if self.last_cmd_t is None else t - self.last_cmd_t
        if math.isfinite(gap) and gap > 1.5 * self.period_s:
            # steps were skipped: restart from where the vehicle is
            self.link.restart(self.controller)
        ref = None if arrived else self.ref
        vs, ws = self.link.follow(t, self.controller, ref, s, pred)
        self.last_cmd_t = t
        msg = self.link.send(t, pred.effect_t, vs, ws, path_id=self.path_id, controller=self.kind)
        return [Emit(stream="cmd", msg=msg)]
