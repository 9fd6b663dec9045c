"""The onboard tracker as the planner predicts it: its controller rolled out on the path it follows.

With ``controller.placement = "onboard"`` the planner sends paths, not commands, yet it plans
from where the vehicle will be when a path reaches the tracker. The link's prediction runs
along the commands sent (command/timeline.py); with none sent it predicted a vehicle under
none, holding its start course while the tracker turned it along the path, so plans began
where the vehicle was not and replans chased deviations of the prediction's own.

The tracker closes its loop onboard, on estimates the planner sees seconds later (over an
acoustic modem, tens of seconds). So the shadow does not replay commands: it runs the same
controller in closed loop on the response model (response.py), from the newest estimate's
fix to the time a path sent now takes effect, on the path the tracker follows at each instant
of that span. Which path that is, and since when, the tracker says in its acknowledgements
(PathAck): a path is in force onboard only once it got there, or never; a path sent is taken
as there one downlink delay later until its acknowledgement tells. Without one, or arrived,
the tracker stops, and so does the rollout. A new estimate or a new acknowledgement
restarts the rollout; otherwise each step extends it by a step.
"""

from __future__ import annotations

import copy
import math
from bisect import bisect_right

from common.messages import StateEstimate
from services.control.command.link import (
    Prediction,
    StationKeeper,
    basis_time,
    believed_current,
    shrunk,
)
from services.control.command.response import Pose
from services.control.controllers.base import Controller, predict_pose
from services.control.loop import CommandLoop
from services.planner.shaping.path_arc_reference import PathArcReference

# the paths put in force kept for an acknowledgement that comes late (a newer one is usual)
KEEP_PATHS = 8


class TrackerShadow:
    """The paths put in force by number, which one the tracker followed since when (by its
    acknowledgements), and the tracker rolled out from the newest estimate (`predict`)."""

    def __init__(self, loop: CommandLoop[PathArcReference]) -> None:
        self.loop = loop
        self.step_s = loop.period_s
        self._refs: dict[int, PathArcReference | None] = {}
        self._since: list[float] = []  # when the tracker took each path it told of ...
        self._ids: list[int] = []  # ... and its number, in that order
        self._expected: dict[int, float] = {}  # when each path put in force is expected there
        self._key: tuple[float, int, int] | None = None  # (estimate stamp, paths told, put)
        self._times: list[float] = []  # the rollout: its times, states and commands
        self._poses: list[Pose] = []
        self._cmds: list[tuple[float, float]] = []
        self._roll: Controller | None = None
        self._keep: StationKeeper | None = None
        self._path = -1  # the path the rollout's controller was last on
        self._arrived = False

    def put(self, path_id: int, ref: PathArcReference | None, expected_t: float) -> None:
        """Path `path_id` put in force (None: a NO_PATH, which stops the tracker), expected
        at the tracker at `expected_t` (s): taken then until its acknowledgement says when."""
        self._refs[path_id] = ref
        self._expected[path_id] = expected_t
        for old in [i for i in self._refs if i <= path_id - KEEP_PATHS]:
            del self._refs[old], self._expected[old]

    def _told(self) -> None:
        """Take the newest acknowledgement (command/inputs.py): a path taken since."""
        ack = self.loop.inputs.ack
        if ack is None or (self._ids and ack.path_id <= self._ids[-1]):
            return
        self._since.append(ack.since)
        self._ids.append(ack.path_id)

    def followed_at(self, t: float) -> int:
        """The path the tracker followed at time t: as it told, and a newer one put in force
        from when it is expected there (0: none)."""
        told = self._ids[-1] if self._ids else 0
        sent = [i for i, t_exp in self._expected.items() if i > told and t >= t_exp]
        if sent:
            return max(sent)
        i = bisect_right(self._since, t)
        return self._ids[i - 1] if i else 0

    def predict(self, t: float, est: StateEstimate, effect_t: float) -> Prediction:
        """The state now and at effect_t (a path sent now there), the tracker rolled out from
        the estimate's fix (carried back to it, as command/link.py does) in the link's
        model, the current of the estimate included."""
        self._told()
        key = (est.stamp, len(self._ids), max(self._expected, default=0))
        model = self.loop.link.model
        if key != self._key:
            self._key = key
            t_b = basis_time(est)
            pose: Pose = (est.x, est.y, est.theta, est.v, est.w)
            self._times = [t_b]
            self._poses = [predict_pose(pose, -est.predicted_s, model.current_mps)]
            self._cmds = []
            self._roll = copy.deepcopy(self.loop.controller)
            self._roll.current = believed_current(est)
            self._roll.sway = shrunk(est.sway, est.sway_std)
            self._path, self._arrived = -1, False
            self._keep = self.loop.link.station_keeper()  # in the estimate's current
        while self._times[-1] < effect_t:
            self._extend()
        return Prediction(now=self._at(t), effect_t=effect_t, at_effect=self._at(effect_t))

    def _extend(self) -> None:
        """One step more of the rollout: the tracker's command on the state it reached."""
        roll, model = self._roll, self.loop.link.model
        assert roll is not None
        t, pose = self._times[-1], self._poses[-1]
        path = self.followed_at(t)
        if path != self._path:  # the tracker restarts its controller on a new path
            self._path = path
            roll.reset()
        goal, arrive_m = self.loop.arrival.goal, self.loop.arrival.arrive_m
        self._arrived = self._arrived or math.hypot(pose[0] - goal[0], pose[1] - goal[1]) <= (
            arrive_m
        )
        ref = None if self._arrived else self._refs.get(path)
        if ref is not None:
            v, w = roll.command(t, pose, ref)
        else:  # a stop: in a current it keeps station (command/link.py `stop`)
            v, w = (0.0, 0.0) if self._keep is None else self._keep(pose)
        self._cmds.append((v, w))
        self._poses.append(model.advance(pose, v, w, self.step_s))
        self._times.append(t + self.step_s)

    def _at(self, t: float) -> Pose:
        """The rolled-out state at time t (between two steps: on from the one before)."""
        i = max(0, bisect_right(self._times, t) - 1)
        t_i, pose = self._times[i], self._poses[i]
        if t <= t_i or i >= len(self._cmds):
            return pose
        v, w = self._cmds[i]
        return self.loop.link.model.advance(pose, v, w, t - t_i)
