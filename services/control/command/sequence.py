"""Packet-based predictive commands: the controller rolled forward over a horizon on a copy.

Networked predictive control (G. P. Liu, Y. Xia, J. Chen, D. Rees, W. Hu, "Networked
predictive control of systems with random network delays in both forward and feedback
channels", IEEE Trans. Ind. Electron. 54(3), 2007); packet-based control: the controller
sends, in one packet, the controls u(t | t), u(t + T | t), ..., u(t + nT | t) it predicts
for the times ahead, and the actuator applies the one for its current time from the newest
packet it holds. Here, at the planner's step t with control period T:

    x(t | t)          the state predicted for now: the estimate carried forward with the
                      commands already sent (timeline.py), in flight included
    u_k = C(x(t + kT | t)),  k = 0..n             the controller C on the predicted state
    x(t + (k+1)T | t) = f(x(t + kT | t), applied)  response.py; `applied` is what the vehicle
                      will apply: the commands sent before this one until this one arrives
                      (t + the expected downlink delay), then u_k

So entry 0 is the command for now, and an entry for time tau is the controller's answer to
the state predicted for tau: whatever the delay turns out to be, the vehicle's watchdog picks
the entry for its own time, and during a loss or an outage it keeps consuming the buffer.

The stop tail (controller.sequence.stop_tail): every entry's speed is capped at
a_brake (t + nT - t_k), a_brake the hull's acceleration bound, so the last entries bring the
vehicle to rest along its path. In normal operation only the first entries are ever applied
(a newer command arrives every period); after a loss or an outage as long as the horizon the
vehicle stops where its path goes, instead of running on blind with its last command and
then braking heading-held (the watchdog's HOLD), which took it off a curve near an
obstacle or the edge of the area.

The controllers are stateful (the fuzzy PID's integral and filtered derivative, the
backstepping virtual reference, the speed ramp): entry 0 comes from the controller itself,
which is advanced once per step as without sequences, and entries 1..n from a deep copy of it,
which is thrown away: the real controller's state never sees a predicted pose, and the whole
computation is a function of the planner's inputs (the same floats in every runtime).

Prepared tails (controller.sequence.fresh_s): of the n + 1 entries, the vehicle applies only
those up to the next command's arrival (at t + T + the downlink delay), unless that command is
lost or late. So a step computes on the newest state only the entries up to fresh_s past
that arrival (`last`), and takes the rest from the sequence the step before prepared for it
(`Prepared`), once its own command was out: the same rollout, run from the state then
predicted for this step's time. Entry k of a command is then u(t + kT | t) while it may
still be applied with the next command on time or up to fresh_s late, and u(t + kT | t - T)
beyond (a prediction one period older, needed only after a loss or in an outage); the step
that sends the command, which is the sample-to-actuation latency of the loop, costs a few
controller evaluations instead of n + 1. A prepared sequence holds only for the step it was
made for, on the same path stopping at the same place, with the controller not restarted
since (`Prepared.holds`); otherwise the step computes every entry, as with fresh_s >= n T.

Reused tails (controller.sequence.reuse_s): rolling a whole sequence out after every step
cost a third of a mission's computation, though a step's newest state mostly lands where the
rollout before predicted it. So when the step's fresh entries end where the prepared tail
they join begins (`Prepared.agrees`: the pose predicted for that entry and its command alike
within the reuse tolerances), the sequence just sent, shifted by one period, is the next
step's prepared one (`Prepared.shifted`): the tail is the continuation of a rollout the newest
state has just been checked to lie on. Its age is bounded (reuse_s): then a tail is rolled out
afresh. A shifted tail brakes to rest one period sooner per shift (its stop tail was made for
an earlier horizon's end): after an outage of most of the horizon the vehicle stops at most
reuse_s early, never later.

Coarse far entries (controller.sequence.fine_s, coarse_step_s): entries past `fine` (3 s) are
applied only blind, once an outage has outlasted them and the vehicle runs on the rest of the
buffer open loop. There the controller is asked every `coarse_every`-th entry (0.3 s) and its
answer held over the entries between, while the rollout still carries the state entry by
entry under what is held: the prediction stays that of the commands sent, and a whole tail
asks the controller ~55 times instead of 101 (docs/notes/0071).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, replace

from common.config.controller import SequenceConfig
from common.scalar import wrap_angle
from services.control.command.response import Pose, ResponseModel
from services.control.command.timeline import CommandTimeline
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Controller
from services.control.controllers.speed import stop_of


def command_sequence(
    controller: Controller,
    ref: ArcLengthReference,
    t: float,
    pose: Pose,
    *,
    n: int,
    step_s: float,
    arrival: float,
    timeline: CommandTimeline,
    model: ResponseModel,
    stop_mps2: float = 0.0,
    last: int | None = None,
    scratch: bool = False,
    poses: list[Pose] | None = None,
    fine: int | None = None,
    coarse_every: int = 1,
) -> tuple[list[float], list[float]]:
    """(vs, ws), each (last + 1,): the commands for t, t + step_s, ..., t + last step_s of a
    sequence of n + 1 (last: n by default), from the state `pose` predicted for t, the new
    command expected at the vehicle at `arrival`; stop_mps2 > 0 brings the vehicle to rest by
    t + n step_s (the stop tail). Entry k is the same floats whatever `last` is. `scratch`: the
    controller is a copy to be thrown away, stepped for every entry (no copy is made).
    `poses`: appended with the state each entry was computed on. Past entry `fine` the
    controller is asked every `coarse_every`-th entry, its answer held between (None: all)."""
    t_end = t + n * step_s
    last = n if last is None else min(last, n)

    def tail(t_k: float, v: float) -> float:
        if stop_mps2 <= 0.0:
            return v
        # min(v, stop_mps2 * max(0.0, t_end - t_k)), written out (the same floats: max(a, b)
        # is b if b > a else a, min(a, b) b if b < a else a): asked at every entry
        left = t_end - t_k
        cap = stop_mps2 * (left if left > 0.0 else 0.0)
        return cap if cap < v else v

    v, w = controller.command(t, pose, ref)
    vs, ws = [tail(t, v)], [w]
    if poses is not None:
        poses.append(pose)
    if last <= 0:
        return vs, ws
    # the real controller's state must not see predictions
    roll = controller if scratch else copy.deepcopy(controller)
    # looked up once: this loop evaluates the controller ~40k times a mission
    command, advance = roll.command, model.advance
    v_prev, w_prev = vs[0], w
    v_asked = v  # the controller's last answer, before the stop tail's cap
    fine = last if fine is None else fine
    for k in range(1, last + 1):
        t_a, t_b = t + (k - 1) * step_s, t + k * step_s
        if t_a < arrival:  # until this command arrives, the vehicle applies the ones before it
            mid = min(arrival, t_b)
            pose = timeline.predict(pose, t_a, mid, model)
            t_a = mid
        if t_a < t_b:  # then entry k - 1 of this one
            pose = advance(pose, v_prev, w_prev, t_b - t_a)
        if k <= fine or (k - fine) % coarse_every == 0:
            v_asked, w_prev = command(t_b, pose, ref)
        # held between asks: the same answer, capped by the stop tail at this entry's time
        v_prev = v_asked if stop_mps2 <= 0.0 else tail(t_b, v_asked)  # tail's test, a call less
        vs.append(v_prev)
        ws.append(w_prev)
        if poses is not None:
            poses.append(pose)
    return vs, ws


@dataclass(frozen=True, kw_only=True)
class ReuseTolerance:
    """How close the newest prediction must lie to a prepared tail for it to be reused."""

    position_m: float
    angle_rad: float  # heading (rad)
    rate_rps: float  # yaw rate and the yaw-rate command (rad/s)
    speed_mps: float

    @staticmethod
    def from_config(cfg: SequenceConfig) -> ReuseTolerance:
        return ReuseTolerance(
            position_m=cfg.reuse_tolerance_m,
            angle_rad=cfg.reuse_tolerance_rad,
            rate_rps=cfg.reuse_tolerance_rate_rps,
            speed_mps=cfg.reuse_tolerance_mps,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class Prepared:
    """A whole sequence made after one step for the next (at `t`), on path `ref` stopping at
    `stop_s`, by a controller restarted `restarts` times: the entries that step takes as they
    are, the states they were computed on, and how many periods ago its tail was rolled out."""

    t: float
    ref: ArcLengthReference
    stop_s: float
    restarts: int
    vs: list[float]
    ws: list[float]
    poses: list[Pose]
    age: int = 0

    def agrees(self, k: int, pose: Pose, v: float, w: float, tol: ReuseTolerance) -> bool:
        """Whether entry k computed afresh, (v, w) on `pose`, lies on this sequence: the state
        and the command alike within `tol` of its entry k."""
        x, y, th, pv, pw = self.poses[k]
        d_xy = math.hypot(pose[0] - x, pose[1] - y)
        return (
            d_xy <= tol.position_m
            and abs(wrap_angle(pose[2] - th)) <= tol.angle_rad
            and abs(pose[3] - pv) <= tol.speed_mps
            and abs(pose[4] - pw) <= tol.rate_rps
            and abs(v - self.vs[k]) <= tol.speed_mps
            and abs(w - self.ws[k]) <= tol.rate_rps
        )

    def shifted(self, t: float) -> Prepared:
        """This sequence one entry on, for the step at t (one period after its own): its last
        entry held one period longer (with the stop tail, at rest)."""
        return replace(
            self,
            t=t,
            vs=[*self.vs[1:], self.vs[-1]],
            ws=[*self.ws[1:], self.ws[-1]],
            poses=[*self.poses[1:], self.poses[-1]],
            age=self.age + 1,
        )

    def holds(self, t: float, ref: ArcLengthReference, restarts: int) -> bool:
        """Whether it was made for a step at t on `ref` as it is now, by the controller as it is."""
        return (
            t == self.t
            and ref is self.ref
            and stop_of(ref) == self.stop_s
            and restarts == self.restarts
        )
