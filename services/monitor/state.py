"""What a monitor knows of one watched run and vehicle, built from its tapped frames: the
dashboard's numbers, its alarms, and the events worth a line; a fleet's vehicles each apart."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from common.bus.gaps import SeqGaps
from common.bus.keys import CLOCK, END
from common.bus.watcher import END_GRACE_S
from common.config.scenario import Scenario
from common.config.world import WorldConfig
from common.estimate_error import estimate_errors
from common.link_table import LinkRow, LinkTable, dropped
from common.messages import (
    LinkStats,
    Message,
    PathMsg,
    RunEnd,
    StateEstimate,
    TruthState,
    VehicleStatus,
    VelocityCommand,
)
from common.runtime.model.dataflow import vehicle_of

TRUTH_KEEP = 256  # truth samples kept to match estimates by stamp (~25 s at 10 Hz)
# truth and estimate run at their own periods: an estimate this far outside the truth kept is
# scored against its nearest end (provisionally: a later truth sample scores it again)
HOLD_S = 0.2


@dataclass
class ServiceLife:
    """A service's liveliness as seen by the monitor: up or gone, since when, restarts."""

    up: bool
    since: float  # wall time (Unix s) of the last change
    restarts: int = 0

    @property
    def state(self) -> str:
        if not self.up:
            return "gone"
        return "restarted" if self.restarts else "up"


@dataclass
class StreamSeen:
    """The newest frame of one stream: when the run's tap got it, how many so far."""

    wall: float
    stamp: float
    count: int = 1
    first_wall: float = 0.0
    event: bool = False  # sent on events (paths), not periodically

    def stale(self, now: float, stale_s: float) -> bool:
        """Older than stale_s and than 3 of its own mean intervals. An event stream, or one
        seen fewer than 3 times (not yet known to be periodic), is never stale."""
        if self.event or self.count < 3:
            return False
        mean_gap = (self.wall - self.first_wall) / (self.count - 1)
        return now - self.wall > max(stale_s, 3 * mean_gap)


@dataclass
class Event:
    """Something worth a line: a mode change, a service gone, an alarm, the run's end."""

    wall: float
    kind: str
    text: str
    data: dict[str, Any] = field(default_factory=dict)


VEHICLE_TYPES = (TruthState, StateEstimate, VehicleStatus, PathMsg, VelocityCommand)
# the run's state: the newest of each is what a dashboard shows. The planner's command is not
# state here: with its future entries it outweighs the rest of the state together, and the
# command the vehicle applies is in its status
STATE_TYPES = (TruthState, VehicleStatus, StateEstimate, PathMsg, RunEnd)
# the frames events are made of (a mode change, a replan, the run's end): a watcher must not
# miss one between two looks at the state
EVENT_TYPES = (VehicleStatus, PathMsg, RunEnd)

# (kind, text, data) of something worth a line, before the run says when and whose
Happening = tuple[str, str, dict[str, Any]]


class VehicleView:
    """One vehicle of a run as the monitor sees it: pose, estimate and its error, mode, the
    command and the path in force; `see` returns what happened worth a line."""

    def __init__(self) -> None:
        self.truth: TruthState | None = None
        self.estimate: StateEstimate | None = None
        self.status: VehicleStatus | None = None
        self.command: VelocityCommand | None = None
        self.path: PathMsg | None = None
        self.paths_seen: set[int] = set()
        self.strategies: dict[str, int] = {}  # the paths seen by the strategy that made them
        self.est_error_m: float | None = None
        self._truths: deque[TruthState] = deque(maxlen=TRUTH_KEEP)

    def see(self, msg: Message) -> list[Happening]:
        """Take one of this vehicle's frames (a VEHICLE_TYPES message)."""
        if isinstance(msg, TruthState):
            self._see_truth(msg)
        elif isinstance(msg, StateEstimate):
            self._see_estimate(msg)
        elif isinstance(msg, VehicleStatus):
            return self._see_status(msg)
        elif isinstance(msg, PathMsg):
            return self._see_path(msg)
        elif isinstance(msg, VelocityCommand):
            if self.command is None or msg.stamp >= self.command.stamp:
                self.command = msg
        return []

    def _see_truth(self, msg: TruthState) -> None:
        if self.truth is None or msg.stamp >= self.truth.stamp:
            self.truth = msg
        self._truths.append(msg)
        if self.estimate is not None:
            self._match_estimate(self.estimate)

    def _see_estimate(self, msg: StateEstimate) -> None:
        if self.estimate is None or msg.stamp >= self.estimate.stamp:
            self.estimate = msg
        self._match_estimate(msg)

    def _match_estimate(self, est: StateEstimate) -> None:
        """An estimate's position error against the truth at its stamp, by the rule metrics.json
        and Foxglove share (common/estimate_error.py); ahead of the truth by up to HOLD_S, against
        the latest truth until the next sample comes (each truth sample scores it again)."""
        errors = estimate_errors([est], self._truths, hold_s=HOLD_S)
        if errors.scored:
            self.est_error_m = float(errors.position_m[0])

    def _see_status(self, msg: VehicleStatus) -> list[Happening]:
        old = self.status
        if old is not None and msg.stamp < old.stamp:
            return []
        self.status = msg
        if old is None:
            # a late joiner learns the last mode change from the status itself
            text = f"mode {msg.mode} since t={msg.mode_since:.2f} s"
            return [("mode", text, {"mode": msg.mode, "since": msg.mode_since})]
        if old.mode != msg.mode:
            text = f"mode {old.mode} -> {msg.mode} at t={msg.mode_since:.2f} s"
            return [("mode", text, {"mode": msg.mode, "from": old.mode, "since": msg.mode_since})]
        return []

    def _see_path(self, msg: PathMsg) -> list[Happening]:
        if msg.path_id in self.paths_seen:
            return []
        self.paths_seen.add(msg.path_id)
        if msg.strategy:  # (services/planner/reasons.py; none from an older planner)
            self.strategies[msg.strategy] = self.strategies.get(msg.strategy, 0) + 1
        old = self.path
        if old is not None and msg.path_id < old.path_id:
            return []  # an older path arriving late: the one in force stays
        self.path = msg
        text = f"path {msg.path_id} {msg.status}"
        text += f" ({msg.length:.1f} m)" if msg.status == "OK" else f" ({msg.reason})"
        text += f" [{msg.strategy}]" if msg.strategy else ""
        data: dict[str, Any] = {"path_id": msg.path_id, "status": msg.status, "reason": msg.reason}
        data |= {"strategy": msg.strategy, "rejected": list(msg.rejected)}
        return [("path", text, data)]

    def snapshot(self, to_goal_m: float | None) -> dict[str, Any]:
        """This vehicle's part of the dashboard (RunState.snapshot)."""
        pose = est = path = None
        if (t := self.truth) is not None:
            pose = {"x": t.x, "y": t.y, "theta": t.theta, "stamp": t.stamp}
        if (e := self.estimate) is not None:
            est = {"x": e.x, "y": e.y, "theta": e.theta, "stamp": e.stamp}
        if (p := self.path) is not None:
            path = {
                "path_id": p.path_id,
                "status": p.status,
                "reason": p.reason,
                "length_m": p.length,
                "replans": max(0, len(self.paths_seen) - 1),
                "strategy": p.strategy,
                "rejected": list(p.rejected),
                "strategies": dict(sorted(self.strategies.items())),
            }
        status, cmd = self.status, self.command
        return {
            "mode": None if status is None else status.mode,
            "mode_since": None if status is None else status.mode_since,
            "pose": pose,
            "estimate": est,
            "speed_mps": None if self.truth is None else self.truth.v,
            "to_goal_m": to_goal_m,
            "est_error_m": self.est_error_m,
            "command": None if cmd is None else {"v": cmd.v, "w": cmd.w, "stamp": cmd.stamp},
            "command_age_s": None if status is None else status.command_age,
            "path": path,
        }


class RunState:
    """A monitor's picture of one run and vehicle; `see` and `liveliness` feed it, `snapshot`
    and `alarms` read it, `take_events` drains what happened since the last call."""

    def __init__(self, run: str, vehicle: str, *, stale_s: float = 2.0) -> None:
        self.run = run
        self.vehicle = vehicle
        self.stale_s = stale_s
        self.scenario: Scenario | None = None
        self.t_mission = 0.0
        # each vehicle's part, by fleet vehicle id ("" for a run's only vehicle)
        self.vehicles: dict[str, VehicleView] = {}
        self.arrived: set[str] = set()  # vehicles that have been at their goals
        self.streams: dict[str, StreamSeen] = {}
        self.services: dict[str, ServiceLife] = {}
        self.links = LinkTable()
        self.end: RunEnd | None = None
        self.heard_at = 0.0  # when (local Unix s) the monitor last got a frame of this run
        self.rejected = 0  # frames that did not decode
        # copies heard on subscriptions that never came: the tap sends them DROP, so a monitor
        # that fell behind (stopped, slow, a thin link) loses them, and says so
        self.copies = SeqGaps()
        self._events: list[Event] = []
        self._alarms: set[str] = set()

    # -- input -------------------------------------------------------------------------------
    def see(self, service: str, stream: str, msg: Message, wall: float) -> None:
        """Take one decoded frame the run's tap got at `wall` (Unix seconds)."""
        key = f"{service}/{stream}"
        seen = self.streams.get(key)
        if seen is None:
            # a path is sent on a replan, however often that came lately: never stale
            event = isinstance(msg, PathMsg | RunEnd)
            self.streams[key] = StreamSeen(wall, msg.stamp, first_wall=wall, event=event)
        else:
            seen.count += 1
            if wall >= seen.wall:
                seen.wall, seen.stamp = wall, msg.stamp
        if not isinstance(msg, RunEnd):
            self.t_mission = max(self.t_mission, msg.stamp)
        if isinstance(msg, TruthState) and stream != "truth":
            return  # a fleet vehicle's "hull": the same states again, for the others' sonars
        if isinstance(msg, VEHICLE_TYPES):
            vid = vehicle_of(service)
            happened = self.view(vid).see(msg)
            if isinstance(msg, TruthState):
                self._arrive(vid)
            for kind, text, data in happened:
                if vid:  # a fleet's vehicle: say which
                    text, data = f"{vid} {text}", {**data, "member": vid}
                self._event(wall, kind, text, data)
        elif isinstance(msg, LinkStats):
            self.links.see(msg)
        elif isinstance(msg, RunEnd):
            # heard once on its subscription and again in the final poll: one event
            if self.end is None:
                self._event(wall, "end", f"run ended at t={msg.stamp:.2f} s: {msg.reason}")
            self.end = msg

    def view(self, vid: str) -> VehicleView:
        """The part of fleet vehicle `vid` ("": the run's only vehicle), made when first seen."""
        v = self.vehicles.get(vid)
        if v is None:
            v = self.vehicles[vid] = VehicleView()
        return v

    # the run's only vehicle (None in a fleet: see `vehicles`)
    @property
    def path(self) -> PathMsg | None:
        return self.view("").path if "" in self.vehicles else None

    @property
    def est_error_m(self) -> float | None:
        return self.view("").est_error_m if "" in self.vehicles else None

    def liveliness(self, service: str, alive: bool, wall: float) -> None:
        """A service's token appeared or vanished."""
        life = self.services.get(service)
        if life is None:
            self.services[service] = ServiceLife(alive, wall)
            self._event(wall, "service", f"{service} {'up' if alive else 'gone'}")
            return
        if life.up == alive:
            return
        life.up, life.since = alive, wall
        if alive:
            life.restarts += 1
            self._event(wall, "service", f"{service} restarted (restart {life.restarts})")
        else:
            self._event(wall, "service", f"{service} gone")

    def over(self, now: float) -> bool:
        """The run ended: its RunEnd arrived, or its clock's token vanished and nothing of the
        run came for END_GRACE_S before `now`. The RunEnd travels behind the tap's copies:
        under load it arrives seconds after the token's end, while the backlog of copies
        drains, so the grace counts from the last frame heard."""
        clock = self.services.get(CLOCK)
        if self.end is not None:
            return True
        if clock is None or clock.up:
            return False
        return now - max(clock.since, self.heard_at) > END_GRACE_S

    # -- output ------------------------------------------------------------------------------
    def _world_of(self, vid: str) -> WorldConfig | None:
        """Vehicle `vid`'s world (its own goal in a fleet), if the scenario is known."""
        if self.scenario is None:
            return None
        if not vid:
            return self.scenario.world
        member = dict(self.scenario.members).get(vid)
        return None if member is None else member.world

    def to_goal_m(self, vid: str = "") -> float | None:
        """How far vehicle `vid` ("": the run's only one) is from its goal, if known."""
        truth = self.vehicles[vid].truth if vid in self.vehicles else None
        world = self._world_of(vid)
        if truth is None or world is None:
            return None
        return math.hypot(truth.x - world.goal.x_m, truth.y - world.goal.y_m)

    def _arrive(self, vid: str) -> None:
        """Note a vehicle within its goal tolerance (for good, as the mission judges it)."""
        if vid in self.arrived:
            return
        d, world = self.to_goal_m(vid), self._world_of(vid)
        if d is not None and world is not None and d <= world.goal_tolerance_m:
            self.arrived.add(vid)

    def ending(self) -> bool:
        """The mission is over by what the monitor sees: every vehicle has been at its goal,
        or the mission time reached max_time_s. Its services leaving and its streams going
        quiet are then no alarm: the RunEnd follows once the driver has their final
        statistics and the metrics (seconds later, a fleet's more)."""
        s = self.scenario
        if s is None:
            return False
        ids = {vid for vid, _ in s.members} or {""}
        return self.t_mission >= s.run.max_time_s or ids <= self.arrived

    def alarms(self, now: float) -> list[str]:
        """What needs a person's attention now (sorted); raising or clearing one is an event."""
        out = []
        quiet_is_fine = self.over(now) or self.ending()
        for name, life in self.services.items():
            if not life.up and not quiet_is_fine:
                out.append(f"service {name} gone")
        if not quiet_is_fine:
            for key, seen in self.streams.items():
                if key != f"{CLOCK}/{END}" and seen.stale(now, self.stale_s):
                    out.append(f"stream {key} stale")
        for vid, v in self.vehicles.items():
            if v.status is not None and v.status.mode == "FAILSAFE":
                out.append(f"{vid or 'vehicle'} FAILSAFE")
            if v.path is not None and v.path.status == "NO_PATH":
                out.append(f"{vid + ' ' if vid else ''}NO_PATH: {v.path.reason}")
        now_set = set(out)
        for a in sorted(now_set - self._alarms):
            self._event(now, "alarm", a, {"raised": True})
        for a in sorted(self._alarms - now_set):
            self._event(now, "alarm", f"cleared: {a}", {"raised": False})
        self._alarms = now_set
        return sorted(out)

    def _event(self, wall: float, kind: str, text: str, data: dict[str, Any] | None = None) -> None:
        self._events.append(Event(wall, kind, text, data or {}))

    def take_events(self) -> list[Event]:
        out, self._events = self._events, []
        return out

    def snapshot(self, now: float) -> dict[str, Any]:
        """Everything the dashboard shows, as JSON-able data (`tidelink monitor --json`): the
        run's only vehicle at the top level; a fleet's under `vehicles`, by id."""
        single = self.vehicles.get("") or VehicleView()
        fleet = {
            vid: v.snapshot(self.to_goal_m(vid)) for vid, v in sorted(self.vehicles.items()) if vid
        }
        return {
            "run": self.run,
            "vehicle": self.vehicle,
            "t_mission": self.t_mission,
            **single.snapshot(self.to_goal_m()),
            **({"vehicles": fleet} if fleet else {}),
            "streams": {
                k: {"age_s": round(now - s.wall, 3), "count": s.count, "stamp": s.stamp}
                for k, s in sorted(self.streams.items())
            },
            "services": {
                k: {"state": life.state, "since": life.since, "restarts": life.restarts}
                for k, life in sorted(self.services.items())
            },
            "links": {row.link: _link_columns(row) for row in self.links.rows()},
            "alarms": self.alarms(now),
            "end": None
            if self.end is None
            else {"reason": self.end.reason, "t_end_s": self.end.stamp, "ticks": self.end.ticks},
            "rejected": self.rejected,
            "copies_lost": self.copies.total,
        }


def _link_columns(row: LinkRow) -> dict[str, int | float]:
    """A link's row as the dashboard shows it: the sender's part (sent, delivered, lost, the
    modelled delays) and the receiver's (the measured delays), each once it was heard."""
    out: dict[str, int | float] = {}
    if (c := row.counters) is not None:
        out.update(
            sent=c.sent,
            delivered=c.delivered,
            lost=dropped(c),
            modelled_p50_s=c.delay_p50,
            modelled_p95_s=c.delay_p95,
        )
    if (d := row.measured) is not None:
        out.update(measured_p50_s=d.delay_p50, measured_p95_s=d.delay_p95)
    return out
