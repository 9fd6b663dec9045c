"""One commanding step's frame, for the planner and the onboard tracker alike.

Both cores steer the vehicle the same way around their own business: the newest plausible
estimate (command/inputs.py), arrival at the goal (command/arrival.py), no command from an
estimate too old for the measured delay to explain (the link's staleness), the controller
restarted after skipped steps, and the command (sequence) sent over the link (command/link.py).
Writing that frame once keeps the planner's and the tracker's commands identical by
construction, which the placement tests pin (tests/test_placement.py).
"""

from __future__ import annotations

import logging
import math
from typing import Generic, TypeVar

from common.config.controller import ControllerConfig
from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from common.messages import StateEstimate
from common.runtime.model.core import Emit
from services.control.command.arrival import Arrival
from services.control.command.inputs import LoopInputs
from services.control.command.link import CommandLink, Hold, Prediction
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Limits
from services.control.controllers.factory import make_controller

Commands = tuple[list[float], list[float]]  # speeds and yaw rates: now, then the sequence

# steps missed for longer than this many periods leave the controller's state (virtual
# reference, integrals, speed ramp) as old as the silence: it restarts from the vehicle
RESTART_AFTER_PERIODS = 1.5

# the path a core follows: the planner's and the tracker's own kind of reference
R = TypeVar("R", bound=ArcLengthReference)


class CommandLoop(Generic[R]):
    """The link, the controller, the judged inputs and arrival of a core that commands the
    vehicle, with the path it follows (`ref`, numbered `path_id`; None: stop)."""

    def __init__(
        self,
        planner: PlannerConfig,
        controller: ControllerConfig,
        vehicle: VehicleConfig,
        world: WorldConfig,
        log: logging.Logger,
        *,
        expected_downlink_s: float = 0.0,
    ) -> None:
        self.period_s = planner.period_s
        self.kind = controller.kind
        # delays measured, the state predicted, commands (sequences) sent: command/link.py
        self.link = CommandLink(
            planner,
            controller,
            vehicle,
            expected_downlink_s=expected_downlink_s,
            start_speed_mps=world.start.speed_mps,
        )
        self.limits = Limits.from_vehicle(vehicle, yaw_lag_lead=controller.yaw_lag_lead)
        self.controller = make_controller(controller, self.limits)
        # the newest plausible estimate; the link told of estimates and statuses (their delays)
        self.inputs = LoopInputs(world.area, self.link, log)
        self.ref: R | None = None
        self.path_id = 0  # of the path followed (0: none yet)
        g = world.goal
        self.arrival = Arrival((g.x_m, g.y_m), world.goal_tolerance_m)
        self.stale_skips = 0  # steps without a command because the estimate was too old
        self.last_cmd_t: float | None = None  # when the last command was sent

    def begin(self, t: float) -> tuple[StateEstimate, Prediction] | None:
        """The estimate to steer from and the vehicle predicted to when a command sent at t
        takes effect; None when there is none yet, or it is stale (counted in stale_skips):
        the uplink is out, and commanding from a pose extrapolated this far would steer blind,
        so nothing is sent; the vehicle runs out its buffer of commands, then its watchdog
        holds. Arrival is updated first, from the estimate."""
        s = self.inputs.state
        if s is None:
            return None
        self.arrival.update(s.x, s.y)
        if self.link.stale(t, s):
            self.stale_skips += 1
            return None
        return s, self.link.predict(t, s)

    def gap_s(self, t: float) -> float:
        """Time since the last command was sent (s; inf before the first)."""
        return math.inf if self.last_cmd_t is None else t - self.last_cmd_t

    def skipped(self, t: float) -> bool:
        """Whether steps were skipped since the last command (RESTART_AFTER_PERIODS)."""
        gap = self.gap_s(t)
        return math.isfinite(gap) and gap > RESTART_AFTER_PERIODS * self.period_s

    def restart(self) -> None:
        """Restart the controller from where the vehicle is (command/link.py)."""
        self.link.restart(self.controller)

    def take(self, ref: R | None) -> None:
        """Follow `ref` from now on (None: stop); a new path restarts the controller."""
        self.ref = ref
        if ref is not None:
            self.restart()

    def follow(
        self, t: float, s: StateEstimate, pred: Prediction, ref: R | None, *, hold: Hold = "station"
    ) -> Commands:
        """The controller's commands on `ref` (a stop without one; `hold`: the link's)."""
        return self.link.follow(t, self.controller, ref, s, pred, hold=hold)

    def steer(
        self, t: float, s: StateEstimate, pred: Prediction, ref: R | None, *, hold: Hold = "station"
    ) -> Emit:
        """The command sent at t on `ref` (`follow`, then `send`; None: a stop)."""
        return self.send(t, pred.effect_t, self.follow(t, s, pred, ref, hold=hold))

    def step(self, t: float) -> list[Emit]:
        """A step of a core with no business of its own (the onboard tracker): the command
        for the newest estimate on the path followed (arrived: a stop), the controller
        restarted after skipped steps; nothing without a fresh estimate (`begin`)."""
        begun = self.begin(t)
        if begun is None:
            return []
        s, pred = begun
        if self.skipped(t):
            self.restart()
        return [self.steer(t, s, pred, None if self.arrival.arrived else self.ref)]

    def send(self, t: float, effect_t: float, vs_ws: Commands) -> Emit:
        """The command (sequence) sent at t to take effect at effect_t, on stream 'cmd'."""
        self.last_cmd_t = t
        msg = self.link.send(t, effect_t, *vs_ws, path_id=self.path_id, controller=self.kind)
        return Emit(stream="cmd", msg=msg)

    def prepare(self, t_next: float) -> None:
        """Once this step's command is out: the sequence for the step at t_next (command/link)."""
        if self.ref is not None and not self.arrival.arrived:
            self.link.prepare(t_next, self.controller, self.ref)
