"""The planner's end of the networked loop: delays measured, the state predicted, commands sent.

- delays measured, not assumed: the uplink delay is the median age of the estimates as they
  arrive (common/control/delay.py); the downlink delay is the vehicle's own measurement on
  commands (VehicleStatus: median + jitter_margin_k x jitter), the network's configured delay
  of planner/cmd until the vehicle has measured one;
- staleness is age *beyond* the uplink delay: an estimate is stale when t - stamp - uplink
  delay > max_estimate_age_s, so a steady 1 s delay is not an outage, a silence still is;
- with command sequences on (controller.sequence.horizon_s > 0): the state is predicted from
  the estimate with the commands already sent, in flight included (timeline.py, the vehicle
  modelled by response.py), to now and to the time this command takes effect (now + the
  downlink delay), and each command carries the controller's commands over the horizon
  (sequence.py): those the vehicle may apply before the next command is fresh_s overdue
  computed in the step, the rest prepared after the step before (`prepare`, sequence.py's
  "Prepared tails"), so the command goes out after a few controller evaluations;
- with them off (the ablation): single commands, each computed as before sequences existed,
  the controller predicting the estimate forward with its constant twist over the estimate's
  age plus the downlink delay.
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Literal

from common.config.controller import ControllerConfig
from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.control import DelayMeter
from common.messages import StateEstimate, VehicleStatus, VelocityCommand
from common.scalar import clamp, wrap_angle
from services.control.command.response import Pose, ResponseModel
from services.control.command.sequence import Prepared, ReuseTolerance, command_sequence
from services.control.command.timeline import CommandTimeline
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Controller, predict_pose
from services.control.controllers.speed import stop_of

# the yaw rate the vehicle has is taken from the commands of the last 3 yaw time constants
YAW_SETTLE_TAUS = 3.0
# a stop keeps station against a current at least this fast (m/s; a slower one is the
# estimate's wander in still water), turning into it with this gain (1/s) on the heading error
STATION_KEEP_MPS = 0.1
STATION_GAIN_PS = 0.5
# ... but with an obstacle close upstream it makes way at this fraction of the current only,
# so that the current carries it back clear of the obstacle instead of holding it there
GIVE_WAY_FRACTION = 0.5
# how a stop holds in a current (`CommandLink.stop`): keeping station head to it, giving way
# (an obstacle close upstream: GIVE_WAY_FRACTION of its speed), or drifting with it, no way
# made (coming about would sweep the hull into an obstacle: planner/stopping.py)
Hold = Literal["station", "give_way", "drift"]


@dataclass(frozen=True, kw_only=True, slots=True)
class Prediction:
    """The vehicle's state now, and at the time a command sent now takes effect (`effect_t`)."""

    now: Pose
    effect_t: float
    at_effect: Pose


@dataclass(frozen=True, kw_only=True, slots=True)
class StationKeeper:
    """Station keeping in a current: head into it (`upstream`, rad) and make way at v_hold."""

    upstream: float
    v_hold: float
    v_turn: float  # how fast it comes about, facing downstream
    r_min: float

    def __call__(self, pose: Pose) -> tuple[float, float]:
        """The command (v, w) for a vehicle in state `pose`."""
        _, _, th, v, _ = pose
        err = wrap_angle(self.upstream - th)
        # facing away from the current, making way at its speed carries the vehicle
        # downstream while it turns at v / R_min (a minute to come about): it comes about
        # at up to cruise speed, the same circle in a fraction of the time, then holds
        v_cmd = self.v_hold + (self.v_turn - self.v_hold) * 0.5 * (1.0 - math.cos(err))
        cap = max(v, 0.0) / self.r_min
        return v_cmd, clamp(STATION_GAIN_PS * err, -cap, cap)


class CommandLink:
    """Measured delays, staleness, prediction along the commands sent, and the commands."""

    def __init__(
        self,
        planner: PlannerConfig,
        controller: ControllerConfig,
        vehicle: VehicleConfig,
        *,
        expected_downlink_s: float = 0.0,
        start_speed_mps: float = 0.0,
    ) -> None:
        self.max_estimate_age_s = planner.max_estimate_age_s
        self.configured_downlink_s = expected_downlink_s
        self.jitter_margin_k = controller.jitter_margin_k
        self.compensate = controller.delay_compensation
        self.entries = controller.sequence.entries(planner.period_s)  # n; 0: single commands
        # past entry `fine`, the controller is asked every coarse_every-th entry (sequence.py)
        self.fine, self.coarse_every = controller.sequence.coarse(planner.period_s)
        self.step_s = round(planner.period_s * 1000) / 1000  # the wire's whole milliseconds
        self.fresh_s = controller.sequence.fresh_s
        # a sent sequence is shifted into the next step's prepared one while its tail is at
        # most this many periods old and the newest state lies on it (sequence.py)
        self.reuse_periods = int(controller.sequence.reuse_s / self.step_s + 1e-9)
        self.reuse_tolerance = ReuseTolerance.from_config(controller.sequence)
        self._prepared: Prepared | None = None  # the sequence the last step made for the next
        self._sent: Prepared | None = None  # the one this step sent, if its tail may be reused
        self.tails_rolled = 0  # prepared tails rolled out afresh
        self.tails_reused = 0  # ... and reused, shifted from the sequence sent
        self._last_basis: tuple[float, Pose] | None = None  # (t, state predicted) of a sequence
        self._restarts = 0  # controller restarts: a sequence prepared before one is void
        self.model = ResponseModel.from_vehicle(vehicle)  # in the newest estimate's current
        self.current_known = False
        self.doubted_current_mps = (0.0, 0.0)  # `doubted_current` of the newest estimate
        self.position_std_m = 0.0  # `position_std` of the newest estimate
        # the stop tail brakes at the hull's bound (sequence.py); 0: none
        self.stop_mps2 = vehicle.accel_max_mps2 if controller.sequence.stop_tail else 0.0
        self.cruise_mps = vehicle.cruise_speed_mps  # how fast a station keeper turns about
        self.timeline = CommandTimeline(vehicle.watchdog, vehicle.v_min_mps, start_speed_mps)
        self.uplink = DelayMeter(planner.delay_window)  # ages of the estimates as they arrive
        self.status: VehicleStatus | None = None  # the vehicle's newest status (by stamp)

    @property
    def horizon_s(self) -> float:
        """How far past its stamp a command reaches (s)."""
        return self.entries * self.step_s

    def on_estimate(self, t: float, est: StateEstimate) -> None:
        """An estimate delivered at t: the age of its information then is a sample of the
        uplink delay."""
        self.uplink.add(t - basis_time(est), est.stamp)

    def on_status(self, status: VehicleStatus) -> None:
        if self.status is None or status.stamp >= self.status.stamp:
            self.status = status

    @property
    def downlink_s(self) -> float:
        """The downlink delay to compensate (s): measured by the vehicle plus the jitter
        margin, or the configured one until the vehicle has measured any."""
        st = self.status
        if st is None or st.delay_samples == 0:
            return self.configured_downlink_s
        return max(0.0, st.delay_s + self.jitter_margin_k * st.delay_jitter_s)

    @property
    def loop_delay_s(self) -> float:
        """The loop's measured delay (s): the estimate's age as it arrives plus the downlink
        delay compensated; how far ahead the vehicle's state is predicted."""
        return max(0.0, self.uplink.delay_s) + self.downlink_s

    def age_beyond_delay(self, t: float, est: StateEstimate) -> float:
        """How much older the estimate's information is at t than the uplink delay makes it
        anyway (s)."""
        return t - basis_time(est) - max(0.0, self.uplink.delay_s)

    def stale(self, t: float, est: StateEstimate) -> bool:
        return self.age_beyond_delay(t, est) > self.max_estimate_age_s

    def predict(self, t: float, est: StateEstimate) -> Prediction:
        """The state now and when a command sent now takes effect. Sequences on and delay
        compensated: carried forward from the estimate with the commands sent; otherwise the
        estimate as it is (without sequences the controller compensates on its own)."""
        pose: Pose = (est.x, est.y, est.theta, est.v, est.w)
        self.model = self.model.with_current(*believed_current(est))
        self.doubted_current_mps = doubted_current(est)
        self.position_std_m = position_std(est)
        # a current is worth keeping station against once it is told from the fixes' noise
        self.current_known = current_told(est)
        t_b = basis_time(est)
        settle = YAW_SETTLE_TAUS * self.model.tau_w_s
        self.timeline.forget_before(t_b - settle)
        if not (self.entries and self.compensate):
            return Prediction(now=pose, effect_t=t, at_effect=pose)
        # the estimator carried its newest fused fix to the stamp at constant twist: back along
        # that arc to the fix, then forward with the commands the vehicle was applying since
        x, y, th, v, w = predict_pose(pose, -est.predicted_s, self.model.current_mps)
        # the yaw rate there: the filter's is noisy (a differenced compass), so the yaw loop is
        # run over the commands of the last YAW_SETTLE_TAUS time constants from it (left with
        # e^-3 of its error; docs/notes/planner-yaw-rate-from-commands.md)
        # (the twist alone: the pose predicted along would be thrown away)
        w = self.timeline.predict(pose, t_b - settle, t_b, self.model, True)[4]
        now = self.timeline.predict((x, y, th, v, w), t_b, t, self.model)
        effect_t = t + self.downlink_s
        at_effect = self.timeline.predict(now, t, effect_t, self.model)
        return Prediction(now=now, effect_t=effect_t, at_effect=at_effect)

    def restart(self, controller: Controller) -> None:
        """Restart the controller (its state is as old as a silence, or a new path is taken):
        a sequence prepared by it before is void."""
        controller.reset()
        self._restarts += 1

    def fresh_last(self, t: float, effect_t: float) -> int:
        """The last entry a step at t computes on the newest state: the vehicle may apply it
        before the next command (due at effect_t + step_s) is fresh_s overdue."""
        due = effect_t - t + self.step_s + self.fresh_s
        return min(self.entries, int(due / self.step_s + 1e-9))

    def control(
        self,
        t: float,
        controller: Controller,
        ref: ArcLengthReference,
        est: StateEstimate,
        pred: Prediction,
    ) -> tuple[list[float], list[float]]:
        """The commands (vs, ws), each (n + 1,), for t, t + step_s, ..., t + n step_s: the
        first ones computed now, the rest from the sequence prepared for this step if it holds
        (sequence.py)."""
        controller.current = self.model.current_mps
        controller.sway = shrunk(est.sway, est.sway_std)
        if not self.entries:  # as before sequences: the controller compensates the latency
            latency = max(0.0, t - est.stamp) + self.downlink_s
            v, w = controller.command(t, (est.x, est.y, est.theta, est.v, est.w), ref, latency)
            return [v], [w]
        prepared, self._prepared = self._prepared, None
        self._last_basis = (t, pred.now)
        last = self.fresh_last(t, pred.effect_t)
        if prepared is None or last >= self.entries or not prepared.holds(t, ref, self._restarts):
            last = self.entries
        poses: list[Pose] = []
        vs, ws = self._sequence(controller, ref, t, pred.now, pred.effect_t, last=last, poses=poses)
        age = 0  # of the tail: all computed now
        if last < self.entries:
            assert prepared is not None
            vs.extend(prepared.vs[last + 1 :])
            ws.extend(prepared.ws[last + 1 :])
            poses.extend(prepared.poses[last + 1 :])
            on_tail = prepared.agrees(last, poses[last], vs[last], ws[last], self.reuse_tolerance)
            age = prepared.age if on_tail else self.reuse_periods
        self._sent = self._made(t, ref, vs, ws, poses, age) if age < self.reuse_periods else None
        return vs, ws

    def _made(
        self,
        t: float,
        ref: ArcLengthReference,
        vs: list[float],
        ws: list[float],
        poses: list[Pose],
        age: int = 0,
    ) -> Prepared:
        """A sequence for the step at t on `ref` as it is, by the controller as it is."""
        return Prepared(
            t=t,
            ref=ref,
            stop_s=stop_of(ref),
            restarts=self._restarts,
            vs=vs,
            ws=ws,
            poses=poses,
            age=age,
        )

    def prepare(self, t_next: float, controller: Controller, ref: ArcLengthReference) -> None:
        """After a step's command is out: the whole sequence for the step at t_next, on a copy
        of the controller, from the state predicted then under the commands sent (this step's
        included); that step computes its first entries afresh and takes the rest from it."""
        basis, self._last_basis = self._last_basis, None
        sent, self._sent = self._sent, None
        if basis is None or self.fresh_last(t_next, t_next + self.downlink_s) >= self.entries:
            return  # no sequence this step, or the next one computes every entry anyway
        t, now = basis
        # the very next step (whole microseconds), on the path and by the controller as sent
        if (
            sent is not None
            and abs(t_next - t - self.step_s) < 1e-6
            and sent.holds(t, ref, self._restarts)
        ):
            self._prepared = sent.shifted(t_next)
            self.tails_reused += 1
            return
        start = self.timeline.predict(now, t, t_next, self.model)
        poses: list[Pose] = []
        vs, ws = self._sequence(
            copy.deepcopy(controller),
            ref,
            t_next,
            start,
            t_next + self.downlink_s,
            scratch=True,
            poses=poses,
        )
        self._prepared = self._made(t_next, ref, vs, ws, poses)
        self.tails_rolled += 1

    def _sequence(
        self,
        controller: Controller,
        ref: ArcLengthReference,
        t: float,
        pose: Pose,
        arrival: float,
        *,
        last: int | None = None,
        scratch: bool = False,
        poses: list[Pose] | None = None,
    ) -> tuple[list[float], list[float]]:
        return command_sequence(
            controller,
            ref,
            t,
            pose,
            n=self.entries,
            step_s=self.step_s,
            arrival=arrival,
            timeline=self.timeline,
            model=self.model,
            stop_mps2=self.stop_mps2,
            last=last,
            scratch=scratch,
            poses=poses,
            fine=self.fine,
            coarse_every=self.coarse_every,
        )

    def follow(
        self,
        t: float,
        controller: Controller,
        ref: ArcLengthReference | None,
        est: StateEstimate,
        pred: Prediction,
        *,
        hold: Hold = "station",
    ) -> tuple[list[float], list[float]]:
        """The controller's commands (sequence) on `ref`, or a stop without a feasible path
        (rather than drive into something; `hold`: stop's). Every path leaves along the
        vehicle's heading, a way out of contact included (safety/recover.py: arcs within
        R_min), so the controller follows it from the start."""
        if ref is None:
            return self.stop(t, pred, hold=hold)
        return self.control(t, controller, ref, est, pred)

    def stop(
        self, t: float, pred: Prediction, *, hold: Hold = "station"
    ) -> tuple[list[float], list[float]]:
        """Commands that stop the vehicle over ground and keep it there over the horizon: in
        still water, zeros; in a current, station keeping (a stopped vehicle drifts with the
        current, out of its place and maybe out of the area): it turns into the current and
        makes way through the water as fast as the current flows, so it holds its ground
        (entries rolled out on the response model, as a sequence's are), once the estimate
        tells the current from its fixes' noise (twice its standard deviation). `hold`
        "give_way": an obstacle lies close upstream, so it makes way at GIVE_WAY_FRACTION of
        the current and drifts back clear of it, still heading into the current; "drift":
        zeros, the current carries it (coming about would sweep it into an obstacle)."""
        n = self.entries + 1
        keep = None if hold == "drift" else self.station_keeper(give_way=hold == "give_way")
        if keep is None:
            zeros = [0.0] * n
            return zeros, list(zeros)
        pose, vs, ws = pred.at_effect, [], []
        for _ in range(n):
            v_cmd, w = keep(pose)
            vs.append(v_cmd)
            ws.append(w)
            pose = self.model.advance(pose, v_cmd, w, self.step_s)
        return vs, ws

    def station_keeper(self, *, give_way: bool = False) -> StationKeeper | None:
        """What a stop commands in the newest estimate's current (`stop`); None in still
        water, or a current not yet told from the fixes' noise: a stop is zeros."""
        cx, cy = self.model.current_mps
        c = math.hypot(cx, cy)
        if c < STATION_KEEP_MPS or not self.current_known:
            return None
        v_hold = min(c * (GIVE_WAY_FRACTION if give_way else 1.0), self.model.v_max_mps)
        return StationKeeper(
            upstream=math.atan2(-cy, -cx),
            v_hold=v_hold,
            v_turn=max(v_hold, min(self.cruise_mps, self.model.v_max_mps)),
            r_min=self.model.r_min_m,
        )

    def send(
        self,
        t: float,
        effect_t: float,
        vs: list[float],
        ws: list[float],
        *,
        path_id: int,
        controller: str,
    ) -> VelocityCommand:
        """The command message for (vs, ws), recorded as sent (expected at the vehicle at
        effect_t) for the predictions to come."""
        if not self.entries:
            return VelocityCommand(
                stamp=t, v=vs[0], w=ws[0], path_id=path_id, controller=controller
            )
        msg = VelocityCommand.predictive(
            stamp=t,
            v=vs[0],
            w=ws[0],
            path_id=path_id,
            controller=controller,
            step_s=self.step_s,
            v_next=vs[1:],
            w_next=ws[1:],
        )
        # as the vehicle will read them: the future entries quantised on the wire
        self.timeline.add(t, effect_t, self.step_s, (msg.v, *msg.v_next), (msg.w, *msg.w_next))
        return msg


def believed_current(est: StateEstimate) -> tuple[float, float]:
    """The current the loop acts on (m/s): the estimate shrunk by its uncertainty (`shrunk`).
    A current the estimator has barely seen (its first seconds: fix noise it cannot yet tell
    from drift, or still water's wander) is not steered against, nor predicted over a whole
    plan's flight; one it knows well is taken as it is."""
    cx, cy, std = est.current_x, est.current_y, est.current_std
    k = _shrink(cx * cx + cy * cy, std)
    return k * cx, k * cy


def doubted_current(est: StateEstimate) -> tuple[float, float]:
    """The stronger current the estimate may yet settle to (m/s): once the current is told
    from the fixes' noise (more than twice its standard deviation), its mean one standard
    deviation longer; before, the believed one. While the estimator is still learning a
    current, the believed one lags it (it grows from 0 over the first seconds), and a plan
    sized and flown in it alone turns too tight over ground (asking.py, rollout.py)."""
    if not current_told(est):
        return believed_current(est)
    cx, cy, std = est.current_x, est.current_y, est.current_std
    c = math.hypot(cx, cy)
    k = (c + std) / c
    return k * cx, k * cy


def position_std(est: StateEstimate) -> float:
    """The estimate's position standard deviation along its larger axis (m): the square root
    of the largest eigenvalue of its 2x2 position covariance."""
    a, b, c = est.covariance[0], est.covariance[1], est.covariance[6]
    half = 0.5 * (a - c)
    return math.sqrt(max(0.0, 0.5 * (a + c) + math.sqrt(half * half + b * b)))


def current_told(est: StateEstimate) -> bool:
    """The estimated current is told from the fixes' noise: more than twice its standard
    deviation (what station keeping and the doubted current wait for)."""
    return math.hypot(est.current_x, est.current_y) > 2.0 * est.current_std


def _shrink(value2: float, std: float) -> float:
    """The factor an estimate of squared size value2 and standard deviation std is taken at:
    value2 / (value2 + std^2) (1 when either is 0)."""
    if value2 == 0.0 or std == 0.0:
        return 1.0
    return value2 / (value2 + std * std)


def shrunk(value: float, std: float) -> float:
    """A scalar estimate shrunk by its uncertainty (the hull's sway: from 10 Hz fixes alone it
    is mostly their noise; a DVL measures it)."""
    return value * _shrink(value * value, std)


def basis_time(est: StateEstimate) -> float:
    """The time of the information in an estimate: its newest fused fix (the estimator
    predicted it from there to the stamp)."""
    return est.stamp - est.predicted_s
