"""The planner service core: replans on events and tracks the path with the chosen controller.

The command it sends crosses the modelled network to the vehicle, so the network sits inside
the control loop; the planner measures the delays, predicts the vehicle to the time its
command takes effect and sends sequences of commands over a horizon (command/link.py).
Static obstacles come from the chart (the scenario's world); moving ones from the
estimator's tracks, predicted with their velocity and acceleration (paper §2).
"""

from __future__ import annotations

import math

from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from common.messages import ObstacleTracks
from common.runtime.deferred import AtOnce, Deferred
from common.runtime.model.core import Delivery, Emit
from services.control.command.link import Prediction
from services.control.loop import CommandLoop
from services.planner.adoption import Adoption
from services.planner.asking import PlanAsking
from services.planner.fleet import FleetExchange
from services.planner.obstacle_picture import ObstaclePicture, judge_tracks
from services.planner.plan import Obstacles, PlanResult, Pose2D
from services.planner.repeat import PathRepeat
from services.planner.replan import ReplanDecision, ReplanPolicy
from services.planner.result import goal_of
from services.planner.safety.intent import FleetIntents
from services.planner.shadow import TrackerShadow
from services.planner.shaping.path_arc_reference import PathArcReference
from services.planner.stopping import Stopping


class PlannerCore:
    """Consumes estimator/state, estimator/tracks and vehicle/status (the delay the vehicle
    measures on commands); publishes path (on replans) and cmd."""

    def __init__(
        self,
        loop: CommandLoop[PathArcReference],
        planner: PlannerConfig,
        vehicle: VehicleConfig,
        world: WorldConfig,
        *,
        commands: bool = True,
        intents: FleetIntents | None = None,
        pose_every_s: float = 0.0,
        intent_every_s: float = 0.0,
        plans: Deferred[PlanResult] | None = None,
    ) -> None:
        """`loop`: the link, controller, inputs and arrival this core commands with, built from
        the scenario by the dataflow as the tracker's is (services/mission/dataflow.py)."""
        self.cfg = planner
        # where a plan is made: at once, in the step that asks for it (virtual time), or
        # beside the steps, which go on tracking the path in force until it is there (the
        # wall clock: a replan of seconds must not stop the commands; common/runtime/deferred.py)
        self.plans: Deferred[PlanResult] = AtOnce() if plans is None else plans
        # in a fleet, the other vehicles' estimates and paths in, this planner's out (fleet.py)
        self.fleet = FleetExchange(
            intents, pose_every_s=pose_every_s, intent_every_s=intent_every_s
        )
        # False: the controller runs onboard (services/tracker): this core only plans
        self.commands = commands
        self.repeat = PathRepeat(0.0 if commands else planner.path_repeat_s)  # repeat.py
        self.vehicle = vehicle
        self.world = world
        # the link, the controller, the judged inputs, arrival and the path followed
        self.loop = loop
        self.link, self.controller, self.inputs = loop.link, loop.controller, loop.inputs
        self.shadow = TrackerShadow(loop)  # onboard, the tracker's commands predicted (shadow.py)
        self.goal, fixed = goal_of(world)  # eq. (10): theta_f imposed if the scenario gives one
        self.fix_goal_heading = fixed
        self.asking = PlanAsking(
            planner, vehicle, world, self.link, self.plans, self.goal, fix_goal_heading=fixed
        )
        self.policy = ReplanPolicy(
            planner, vehicle_radius_m=vehicle.radius_m, v_ref_mps=vehicle.cruise_speed_mps
        )
        self.seen = ObstaclePicture(world, intents, planner.first_plan_wait_s)
        self.adoption = Adoption(
            planner, self.loop, self.policy, self.goal, cruise_speed_mps=vehicle.cruise_speed_mps
        )
        self.stopping = Stopping(planner, vehicle, world, self.seen, self.asking)
        # a longer silence than this makes the vehicle hold (and the estimate stale): it runs
        # its last command's entries (the sequence's horizon), then hold_after_s on the last
        self.resume_after_s = max(
            planner.max_estimate_age_s, self.link.horizon_s + vehicle.watchdog.hold_after_s
        )

    @property
    def ref(self) -> PathArcReference | None:
        """The path in force (None: stop)."""
        return self.loop.ref

    @property
    def path_id(self) -> int:
        """The number of the last path published (0: none yet)."""
        return self.loop.path_id

    @property
    def stale_skips(self) -> int:
        """Steps without a command because the estimate was too old."""
        return self.loop.stale_skips

    def deliver(self, d: Delivery) -> list[Emit]:
        """Keep the newest estimate and tracks by stamp, unless implausible: a stamp from the
        future (an estimate that never ages, which would hold the place of every later one),
        a pose outside the world, more tracks than a message may carry (planning work grows
        with them) are rejected, counted and logged (command/inputs.py)."""
        msg = d.msg
        if self.fleet.take(d, self.inputs.judge):  # another vehicle's estimate or path
            return []
        if isinstance(msg, ObstacleTracks):
            why = judge_tracks(self.inputs.judge, msg, d.t)
            if why is not None:
                self.inputs.reject("tracks", why, d.t, msg)
            else:
                self.seen.take(msg)
        else:
            self.inputs.offer(d.t, msg)
        return []

    @property
    def inputs_rejected(self) -> dict[str, int]:
        """Estimates, statuses and track sets rejected, by '<stream>.<reason>'."""
        return self.inputs.rejected

    @property
    def tracks(self) -> ObstacleTracks | None:
        """The newest plausible obstacle tracks (obstacle_picture.py)."""
        return self.seen.tracks

    @property
    def last_result(self) -> PlanResult | None:
        """The plan adopted last (adoption.py)."""
        return self.adoption.last_result

    @property
    def stats_counters(self) -> dict[str, int]:
        """The plans this planner declined (adoption.py), and, in a fleet, its steps by each
        other vehicle's intent or track."""
        return {**self.adoption.counters, **self.fleet.counters}

    def step(self, t: float) -> list[Emit]:
        self.fleet.tally(t, self.inputs.state)
        out = self._step(t)
        out.extend(self.fleet.emits(t, self.inputs.state, out))
        return out

    def prepare(self, t_next: float) -> None:
        """Once this step's command is out: the sequence for the step at t_next (command/link)."""
        if self.commands:
            self.loop.prepare(t_next)

    def _step(self, t: float) -> list[Emit]:
        begun = self.loop.begin(t)
        if begun is None:
            return []
        s, pred = begun
        if not self.commands:  # onboard: the tracker's own closed loop predicted (shadow.py)
            pred = self.shadow.predict(t, s, pred.effect_t)
        if self.loop.arrival.arrived:
            hold = self.stopping.hold(pred)
            return [self.loop.steer(t, s, pred, None, hold=hold)] if self.commands else []
        here = Pose2D(x=pred.at_effect[0], y=pred.at_effect[1], theta=pred.at_effect[2])
        # a plan made now starts where the vehicle will be when it takes effect, among the
        # obstacles as they will be then
        t_plan = pred.effect_t
        obstacles = self.seen.at(t_plan)
        decision = self._decide(t, t_plan, here, obstacles)
        if decision.replan:
            if self.ref is not None and math.isfinite(decision.conflict_s):
                # the path in force is unsafe ahead: until its replacement is in force (seconds,
                # in realtime; at once in virtual time), stop short of the first conflict
                self.ref.stop_at(decision.conflict_s - self.cfg.clearance_margin_m)
            self._ask(t, t_plan, here, pred, obstacles, decision.reason)
        made = self.plans.result()
        path = None if made is None else self.adoption.settle(t, pred, self.asking.done(t), made)
        if path is not None:  # onboard, expected at the tracker a downlink delay on (shadow.py)
            self.shadow.put(path.path_id, self.loop.ref, t + self.link.downlink_s)
        sent = self.repeat.outgoing(t, path)  # onboard, a lost path is not final (repeat.py)
        out = [] if sent is None else [Emit(stream="path", msg=sent)]
        if path is None and not decision.replan and self.loop.skipped(t):
            # steps were skipped (a stale estimate): the plan holds, but the controller's state
            # (virtual reference, integrals, speed ramp) is as old as the silence: restart it
            self.loop.restart()
        if self.commands:
            run_out = self.stopping.run_out(pred, self.loop.ref, self.last_result)
            ref = None if run_out else self.loop.ref
            hold = self.stopping.hold(pred) if ref is None else "station"
            out.append(self.loop.steer(t, s, pred, ref, hold=hold))
        return out

    def _decide(
        self, t: float, t_plan: float, here: Pose2D, obstacles: Obstacles
    ) -> ReplanDecision:
        """Whether to plan again at step t (replan.py), for a vehicle `here` at t_plan: not
        while a plan is being made, nor (the first) before the first obstacle tracks; afresh
        after a silence long enough for the vehicle to hold; else as the policy judges."""
        gap = self.loop.gap_s(t)
        if self.plans.running:
            return ReplanDecision(replan=False, detail="a plan is being made")
        if self.path_id == 0 and self.seen.awaiting_first(t):
            return ReplanDecision(
                replan=False, detail="the first plan waits for the first obstacle tracks"
            )
        if math.isfinite(gap) and gap > self.resume_after_s:
            # no command for so long that the vehicle's watchdog made it hold, off the plan:
            # plan and controller state are stale, so plan afresh from the (fresh) estimate
            return ReplanDecision(
                replan=True, reason="resumed", detail=f"no command for {gap:.1f} s"
            )
        current = self.link.model.current_mps
        return self.policy.check(t_plan, here, self.goal, obstacles, current)

    def _ask(
        self,
        t: float,
        t_plan: float,
        here: Pose2D,
        pred: Prediction,
        obstacles: Obstacles,
        why: str,
    ) -> None:
        """Ask for a plan at step t (asking.py): from where the vehicle will be once it is
        made, among the obstacles as they will be then, the way aside in force kept in mind."""
        t_start, start, twist = self.asking.start_of(
            t_plan, here, pred, why, self.ref, self.policy.s_now
        )
        if t_start != t_plan:
            obstacles = self.seen.at(t_start)
        last = self.last_result
        aside = last if self.ref is not None and last is not None and last.short_of_goal else None
        self.asking.ask(
            t, t_start, start, twist, obstacles, why, controller=self.controller, aside=aside
        )

    @property
    def clearance_margin_m(self) -> float:
        """The margin a plan made now aims beyond the required clearance (m; asking.py)."""
        return self.asking.clearance_margin_m
