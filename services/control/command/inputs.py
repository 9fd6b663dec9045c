"""What a commanding core accepts from the loop: estimates, vehicle statuses and path
acknowledgements, judged first.

The planner and the onboard tracker (services/tracker) command the vehicle alike
(command/link.py), so they take its inputs alike: an estimate or a vehicle status is judged
plausible (stamp, pose, speeds; measured delay) or rejected, counted and logged by
'<stream>.<reason>'. An accepted one feeds the link's delay measurements, late ones too
(their delay is real), and the newest estimate by stamp, not the last handed over, is the
one steered from: a backlog or a reordering link may hand an older one over after a newer.
The newest acknowledgement of the onboard tracker (PathAck) is kept the same way.
"""

from __future__ import annotations

import logging

from common.config.world import AreaConfig
from common.guard import Plausibility, RateLimitedLog, Reason, first_reason
from common.guard.rejects import warn_rejected
from common.messages import Message, PathAck, StateEstimate, VehicleStatus
from services.control.command.link import CommandLink


def judge_state(j: Plausibility, m: StateEstimate, now: float) -> Reason | None:
    """Why an estimate is implausible (stamp, pose, speeds), or None."""
    return first_reason(
        j.stamp(m.stamp, now), j.position(m.x, m.y), j.angle(m.theta), j.speed(m.v), j.rate(m.w)
    )


def judge_status(j: Plausibility, m: VehicleStatus, now: float) -> Reason | None:
    """Why a vehicle status is implausible (stamp, measured delay), or None."""
    return first_reason(j.stamp(m.stamp, now), j.delay(m.delay_s, m.delay_jitter_s))


class LoopInputs:
    """The newest plausible estimate and path acknowledgement, the link told of every estimate
    and status accepted, and the count and log of the core's inputs rejected (these and its
    own: `reject`)."""

    def __init__(self, area: AreaConfig, link: CommandLink, log: logging.Logger) -> None:
        self.judge = Plausibility.of_area(area)
        self.link = link
        self.state: StateEstimate | None = None
        self.ack: PathAck | None = None
        self.rejects = RateLimitedLog(log)

    @property
    def rejected(self) -> dict[str, int]:
        """Inputs rejected, by '<stream>.<reason>'."""
        return dict(self.rejects.counts)

    def offer(self, t: float, msg: Message) -> bool:
        """Judge and take an estimate, a vehicle status or a path acknowledgement delivered at
        t; False for any other message (the core's own business)."""
        if isinstance(msg, StateEstimate):
            why = judge_state(self.judge, msg, t)
            if why is not None:
                self.reject("state", why, t, msg)
            else:
                self.link.on_estimate(t, msg)
                if self.state is None or msg.stamp >= self.state.stamp:
                    self.state = msg
        elif isinstance(msg, VehicleStatus):
            why = judge_status(self.judge, msg, t)
            if why is not None:
                self.reject("status", why, t, msg)
            else:
                self.link.on_status(msg)
        elif isinstance(msg, PathAck):
            why = first_reason(self.judge.stamp(msg.stamp, t))
            if why is not None:
                self.reject("ack", why, t, msg)
            elif self.ack is None or msg.stamp >= self.ack.stamp:
                self.ack = msg
        else:
            return False
        return True

    def reject(self, stream: str, why: Reason, t: float, msg: Message) -> None:
        """Count a message of `stream` rejected at t, and log it (rate-limited)."""
        warn_rejected(self.rejects, stream, why, t, msg)
