"""A fleet planner's exchange with the other vehicles: their estimates and paths in, its own out."""

from __future__ import annotations

from common.guard import Plausibility
from common.messages import StateEstimate
from common.runtime.model.core import Delivery, Emit
from common.runtime.model.dataflow import vehicle_of
from services.control.command.inputs import judge_state
from services.planner.broadcast import FleetBroadcast
from services.planner.safety.intent import FleetIntents


class FleetExchange:
    """The other vehicles' broadcast estimates and paths, taken as their intents
    (safety/intent.py), and this planner's own, published (broadcast.py). Outside a fleet
    (`intents` None, both periods 0) nothing passes either way."""

    def __init__(
        self, intents: FleetIntents | None, *, pose_every_s: float, intent_every_s: float
    ) -> None:
        self.intents = intents
        self.broadcast = FleetBroadcast(pose_every_s=pose_every_s, intent_every_s=intent_every_s)

    def take(self, d: Delivery, judge: Plausibility) -> bool:
        """Whether `d` is another vehicle's message, taken here: its path, or its estimate
        unless implausible (`judge`), offered as its intent."""
        other = vehicle_of(d.source)
        if self.intents is None or other not in self.intents.vehicles:
            return False
        msg = d.msg
        if not isinstance(msg, StateEstimate) or judge_state(judge, msg, d.t) is None:
            self.intents.offer(other, msg)
        return True

    def tally(self, t: float, state: StateEstimate | None) -> None:
        """Count this planner's step at t (s) by each other vehicle's intent or track, once
        it has an estimate of its own."""
        if self.intents is not None and state is not None:
            self.intents.tally(t)

    def emits(self, t: float, state: StateEstimate | None, out: list[Emit]) -> list[Emit]:
        """What to publish at step t (s) after the step's own outputs `out` (broadcast.py)."""
        return self.broadcast.emits(t, state, out)

    @property
    def counters(self) -> dict[str, int]:
        """The steps by each other vehicle's intent or track (none outside a fleet)."""
        return self.intents.counters if self.intents is not None else {}
