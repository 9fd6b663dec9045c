"""The tracker core: follows the newest path the planner sent with the chosen controller, onboard.

With ``controller.placement = "onboard"`` the planner (maybe at a topside station, across a
thin acoustic link) sends paths only, and this core, on the vehicle's node, computes the
commands from the onboard estimate: the same controller, speed profile, prediction, command
sequences and input checks as the planner's own (services/control/command/: link.py
`CommandLink.follow`, inputs.py), on a link that is local. A late or lost path costs
nothing but freshness: the tracker keeps following the last one it holds. Every path message
it receives it acknowledges (PathAck, the number of the path it follows), so the planner knows
which path the vehicle is on, and since when, however late or lossy the link.
"""

from __future__ import annotations

from common.guard import first_reason
from common.messages import PathAck, PathMsg
from common.runtime.model.core import Delivery, Emit
from services.control.loop import CommandLoop
from services.planner.geometry.planned_path import PlannedPath, curve_of
from services.planner.shaping.path_arc_reference import PathArcReference


class TrackerCore:
    """Consumes estimator/state, planner/path and vehicle/status; publishes cmd and ack."""

    def __init__(self, loop: CommandLoop[PathArcReference]) -> None:
        """`loop`: the link, controller, inputs and arrival this core commands with, built
        from the scenario by the dataflow (services/mission/dataflow.py `make_tracker`)."""
        self.loop = loop
        self.inputs = loop.inputs
        self._ack_due = False  # a path message came since the last acknowledgement
        self._since = 0.0  # when the path followed was taken

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
                return []
            self._ack_due = True  # a repeat too: the acknowledgement of the last may be lost
            if msg.path_id > self.loop.path_id:
                self._since = d.t
                self._take(msg)
        else:
            self.inputs.offer(d.t, msg)
        return []

    def _take(self, p: PathMsg) -> None:
        """Follow path `p` from now on (a NO_PATH stops the vehicle)."""
        self.loop.path_id = p.path_id
        if p.status != "OK":
            self.loop.take(None)
            return
        try:
            curve = curve_of(p)
        except ValueError as exc:  # well-formed on the wire, but no curve: keep stopping
            self.inputs.rejects.warn(
                "path.curve", p.stamp, "path %d has no curve: %s", p.path_id, exc
            )
            self.loop.take(None)
            return
        self.loop.take(PathArcReference(PlannedPath(curve), p.v_ref))

    def prepare(self, t_next: float) -> None:
        """Once this step's command is out: the sequence for the step at t_next (command/link)."""
        self.loop.prepare(t_next)

    def step(self, t: float) -> list[Emit]:
        """The command for the newest estimate on the newest path (arrived: a stop), and the
        acknowledgement of the path followed when a path message came since the last."""
        out = self.loop.step(t)
        if self._ack_due:
            self._ack_due = False
            ack = PathAck(stamp=t, path_id=self.loop.path_id, since=self._since)
            out.append(Emit(stream="ack", msg=ack))
        return out
