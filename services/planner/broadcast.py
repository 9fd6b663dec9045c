"""A fleet planner's broadcast: the estimate it plans from ("pose"), its newest path ("intent")."""

from __future__ import annotations

from common.messages import PathMsg, StateEstimate
from common.runtime.model.core import Emit


class FleetBroadcast:
    """What a fleet's planner tells the others, and when: others take its estimate, with its
    path, as its intent while it comes (a dead planner's vehicle is a track again). Both
    periods are 0 outside a fleet: nothing is published."""

    def __init__(self, *, pose_every_s: float, intent_every_s: float) -> None:
        self.pose_every_s = pose_every_s  # > 0 in a fleet: publish "pose" this often
        self._next_pose_t = 0.0
        # > 0 in a fleet: publish the newest path on "intent" when it is made and this often
        # after, so that one lost on the way is repaired (a path is made once per replan)
        self.intent_every_s = intent_every_s
        self._intent: PathMsg | None = None
        self._next_intent_t = 0.0

    def emits(self, t: float, state: StateEstimate | None, out: list[Emit]) -> list[Emit]:
        """What to publish at step t (s), after the step's own outputs `out`."""
        more: list[Emit] = []
        if self.pose_every_s > 0.0 and state is not None and t >= self._next_pose_t:
            self._next_pose_t = t + self.pose_every_s - 1e-9
            more.append(Emit(stream="pose", msg=state))
        if self.intent_every_s > 0.0:
            made = [e.msg for e in out if e.stream == "path" and isinstance(e.msg, PathMsg)]
            if made:
                self._intent, self._next_intent_t = made[-1], t
            if self._intent is not None and t >= self._next_intent_t:
                self._next_intent_t = t + self.intent_every_s - 1e-9
                more.append(Emit(stream="intent", msg=self._intent))
        return more
