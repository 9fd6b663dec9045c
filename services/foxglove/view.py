"""The Foxglove view of a run: tidelink messages translated into Foxglove's typed messages.

Pure translation, no I/O: the live bridge (bridge.py) and the MCAP recorder both feed it a
run's frames in order and log what it returns. Scene topics are protobuf messages of
foxglove-sdk (SceneUpdate, PoseInFrame, PosesInFrame, FrameTransform, Log), so the app draws
them natively; plottable series are JSON with a JSON Schema (series.py). Every scene message
is complete in itself (a SceneUpdate clears its topic before drawing), so the newest message
of a topic is all a late subscriber needs.
"""

from __future__ import annotations

import dataclasses
import math
from collections import deque
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np
from foxglove.messages import (
    FrameTransform,
    Log,
    LogLevel,
    PoseInFrame,
    PosesInFrame,
    SceneEntity,
    SceneEntityDeletion,
    SceneEntityDeletionType,
    SceneUpdate,
    Vector3,
)

from common.config.scenario import Scenario
from common.jsonsafe import JsonObject, JsonValue
from common.link_table import LinkRow, LinkTable, dropped
from common.messages import (
    LinkStats,
    Message,
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    PathMsg,
    RunEnd,
    StateEstimate,
    TruthState,
    VehicleStatus,
    VelocityCommand,
)
from common.runtime.model.dataflow import vehicle_of
from common.view import ViewMessage
from common.world import World
from services.foxglove import entities as draw
from services.foxglove import series
from services.foxglove.scene import WORLD, stamp, yaw_pose, yaw_quaternion
from services.foxglove.scoring import EstimateScorer, Scored
from services.foxglove.trail import Trail
from services.mission.metrics import path_points

# -- topics (series.py names the JSON ones) -------------------------------------------------
SCENE_STATIC = "/scene/static"  # area, start, goal, static obstacles
SCENE_MOVING = "/scene/moving"  # moving obstacles where they truly are, at each truth stamp
SCENE_TRACKS = "/scene/tracks"  # the estimator's obstacle tracks, radius + 2 sigma
SCENE_DETECTIONS = "/scene/detections"  # the latest obstacle scan
SCENE_ESTIMATE = "/scene/estimate"  # the vehicle estimate's 2-sigma position ellipse
PLANNER_PATH = "/planner/path"  # the NURBS path in force, its control polygon, earlier replans
POSE_TRUE = "/vehicle/pose_true"
POSE_EST = "/vehicle/pose_est"
TRAIL_TRUE = "/vehicle/trail_true"
TRAIL_EST = "/vehicle/trail_est"
NAV_FIX = "/sensor/nav"  # the noisy navigation fix
TF = "/tf"  # world -> auv (truth) and world -> auv_est, for a panel that follows the vehicle
EVENTS = "/events"  # mode changes, path status changes, the run's end
RUN_TOPICS = frozenset({EVENTS, SCENE_MOVING, TF})  # one of each in a run, fleet or not
# what a fleet's view publishes once for the run, not under each vehicle's id
FLEET_RUN_TOPICS = RUN_TOPICS | {
    SCENE_STATIC,
    series.LINKS.topic,
    series.RUN_INFO.topic,
    series.RUN_END.topic,
}

PATH_SAMPLES = 300  # points of the path in force: smooth at chart scale
REPLAN_SAMPLES = 100  # points of each earlier replan, drawn faint
MAX_REPLANS = 30  # earlier replans kept on the chart
MODE_CODES = {"IDLE": 0, "RUN": 1, "HOLD": 2, "FAILSAFE": 3, "DONE": 4}


# what a fleet vehicle's own view shows (under /<vehicle id>/...); the rest is the run's
VEHICLE_TYPES = (
    TruthState,
    StateEstimate,
    ObstacleTracks,
    ObstacleDetections,
    PathMsg,
    VelocityCommand,
    VehicleStatus,
    NavFix,
)


class FoxgloveView:
    """Translates one run's messages (in order) into view messages; holds what a chart needs
    across messages (trails, earlier replans, the truth to score estimates against).

    A fleet's vehicles each get a view of their own, built from their own scenario (their
    start and goal): its topics under /<vehicle id> (/auv2/vehicle/pose_true,
    /auv2/planner/path, ...), its frames <id> and <id>_est; the events, the links, the run's
    end and the moving obstacles (drawn at the first vehicle's truth stamps) stay the run's.
    """

    def __init__(self, scenario: Scenario, *, vehicle: str = "", draw_moving: bool = True) -> None:
        self.scenario = scenario
        self.world = World(scenario.world)
        self._has_moving = bool(scenario.world.moving) and draw_moving
        self._frame = vehicle or "auv"  # the TF child frame of the truth (+ "_est")
        self._members = {
            vid: FoxgloveView(m, vehicle=vid, draw_moving=i == 0)
            for i, (vid, m) in enumerate(scenario.members)
        }
        self._scorer = EstimateScorer()
        self._trail_true = Trail(spacing_m=0.25, max_poses=4000, period_s=0.5)
        self._trail_est = Trail(spacing_m=0.25, max_poses=4000, period_s=0.5)
        self._replans: deque[tuple[int, np.ndarray]] = deque(maxlen=MAX_REPLANS)
        self._n_paths = 0
        self._paths_seen: set[int] = set()
        self._links = LinkTable()
        self._mode: str | None = None
        self._path_status: str | None = None
        self._n_detections = 0
        self._by_type: dict[type, Callable[[str, Any], list[ViewMessage]]] = {
            TruthState: self._truth_state,
            StateEstimate: self._estimate,
            ObstacleTracks: self._tracks,
            ObstacleDetections: self._detections,
            PathMsg: self._path,
            VelocityCommand: self._command,
            VehicleStatus: self._status,
            NavFix: self._nav,
            LinkStats: self._link_stats,
            RunEnd: self._run_end,
        }

    def static(self) -> list[ViewMessage]:
        """The chart (area, start, goal, static obstacles) and the run's identity."""
        s, g = self.scenario, self.scenario.world.goal
        info: dict[str, JsonValue] = {
            "name": s.run.name,
            "vehicle": s.run.vehicle,
            "seed": s.run.seed,
            "controller": s.controller.kind,
            "runtime": s.runtime.kind,
            "max_time_s": s.run.max_time_s,
            "goal_x_m": g.x_m,
            "goal_y_m": g.y_m,
        }
        chart = draw.chart(s.world, ends=not self._members)
        for vid, m in self._members.items():
            chart += draw.start_and_goal(m.scenario.world, vid)
        return [_replace_all(SCENE_STATIC, 0.0, chart), _json(series.RUN_INFO, info)]

    def translate(self, service: str, stream: str, msg: Message) -> list[ViewMessage]:
        """The view messages one tidelink message gives ([] for a type the view does not show)."""
        if isinstance(msg, TruthState) and stream != "truth":
            return []  # a fleet vehicle's "hull": the same states again, for the others' sonars
        vid = vehicle_of(service)
        member = self._members.get(vid)
        if member is not None and isinstance(msg, VEHICLE_TYPES):
            return [_under(vid, vm) for vm in member.translate(service, stream, msg)]
        handler = self._by_type.get(type(msg))
        return [] if handler is None else handler(service, msg)

    # -- the vehicle -------------------------------------------------------------------------
    def _truth_state(self, service: str, m: TruthState) -> list[ViewMessage]:
        t, g = m.stamp, self.scenario.world.goal
        values = {
            **_motion(m),
            "distance_to_goal_m": math.hypot(m.x - g.x_m, m.y - g.y_m),
            "collided": m.collided,
        }
        clearance = self.world.clearance(m.x, m.y, self.scenario.vehicle.radius_m, t)
        if math.isfinite(clearance):
            values["clearance_m"] = clearance
        out = [
            _proto(POSE_TRUE, _pose(t, m.x, m.y, m.theta)),
            _proto(TF, _transform(self._frame, t, m.x, m.y, m.theta)),
            _json(series.TRUTH, values),
        ]
        if self._has_moving:
            out.append(_replace_all(SCENE_MOVING, t, draw.moving(self.world.obstacles_at(t), t)))
        out += _errors(self._scorer.truth(m))
        return out + _trail(TRAIL_TRUE, self._trail_true, t, m.x, m.y, m.theta)

    def _estimate(self, service: str, m: StateEstimate) -> list[ViewMessage]:
        t = m.stamp
        cov = m.covariance  # 5x5 row-major: x, y, theta, v, w
        values = {
            **_motion(m),
            "std_x_m": math.sqrt(max(0.0, cov[0])),
            "std_y_m": math.sqrt(max(0.0, cov[6])),
            "std_theta_rad": math.sqrt(max(0.0, cov[12])),
        }
        out = [
            _proto(POSE_EST, _pose(t, m.x, m.y, m.theta)),
            _proto(TF, _transform(f"{self._frame}_est", t, m.x, m.y, m.theta)),
            _replace_all(SCENE_ESTIMATE, t, [draw.estimate(m)]),
            _json(series.ESTIMATE, values),
        ]
        out += _errors(self._scorer.estimate(m))
        return out + _trail(TRAIL_EST, self._trail_est, t, m.x, m.y, m.theta)

    def _nav(self, service: str, m: NavFix) -> list[ViewMessage]:
        return [_proto(NAV_FIX, _pose(m.stamp, m.x, m.y, m.heading))]

    def _command(self, service: str, m: VelocityCommand) -> list[ViewMessage]:
        values: dict[str, JsonValue] = {
            "t": m.stamp,
            "v_mps": m.v,
            "w_radps": m.w,
            "path_id": m.path_id,
            "controller": m.controller,
        }
        return [_json(series.CMD, values)]

    def _status(self, service: str, m: VehicleStatus) -> list[ViewMessage]:
        values = {
            "t": m.stamp,
            "mode": m.mode,
            "mode_code": MODE_CODES.get(m.mode, -1),
            "mode_since_s": m.mode_since,
            "v_applied_mps": m.v_applied,
            "w_applied_radps": m.w_applied,
            "command_age_s": m.command_age,
            "commands_applied": m.commands_applied,
            "commands_rejected": m.commands_rejected,
            "commands_clamped": m.commands_clamped,
        }
        out = [_json(series.VEHICLE, values)]
        if m.mode != self._mode:
            level = LogLevel.Warning if m.mode in ("HOLD", "FAILSAFE") else LogLevel.Info
            text = f"vehicle mode {self._mode or '-'} -> {m.mode} at t={m.mode_since:.2f} s"
            out.append(_event(m.stamp, level, service, text))
            self._mode = m.mode
        return out

    # -- obstacles ---------------------------------------------------------------------------
    def _tracks(self, service: str, m: ObstacleTracks) -> list[ViewMessage]:
        # covariance 6x6 row-major, x, y first: entries 0 and 7 are var(x) and var(y)
        worst = max((max(k.covariance[0], k.covariance[7]) for k in m.tracks), default=0.0)
        values = {
            "t": m.stamp,
            "n_tracks": len(m.tracks),
            "max_std_xy_m": math.sqrt(max(0.0, worst)),
            "n_detections": self._n_detections,
        }
        return [_replace_all(SCENE_TRACKS, m.stamp, draw.tracks(m)), _json(series.TRACKS, values)]

    def _detections(self, service: str, m: ObstacleDetections) -> list[ViewMessage]:
        self._n_detections = len(m.detections)
        return [_replace_all(SCENE_DETECTIONS, m.stamp, draw.detections(m))]

    # -- the plan ----------------------------------------------------------------------------
    def _path(self, service: str, m: PathMsg) -> list[ViewMessage]:
        # a fleet's planner sends each path again as its intent, every second: one replan
        if m.path_id in self._paths_seen:
            return []
        self._paths_seen.add(m.path_id)
        t = m.stamp
        self._n_paths += 1
        rejected: list[JsonValue] = list(m.rejected)
        values: dict[str, JsonValue] = {
            "t": t,
            "path_id": m.path_id,
            "status": m.status,
            "ok": int(m.status == "OK"),
            "reason": m.reason,
            "strategy": m.strategy,
            "rejected": rejected,
            "length_m": m.length,
            "f_l": m.f_l,
            "max_curvature_1pm": m.max_curvature,
            "v_ref_mps": m.v_ref,
            "replans": self._n_paths,
        }
        out = [_json(series.PATH, values)]
        ents = []
        if m.status == "OK":
            curve = path_points(m, PATH_SAMPLES)
            ctrl = np.asarray(m.control_points, dtype=np.float64).reshape(-1, 2)
            ents.append(draw.path_in_force(t, curve, ctrl))
            self._replans.append((m.path_id, curve[:: max(1, PATH_SAMPLES // REPLAN_SAMPLES)]))
        # every path kept (this one too) drawn faint under the one in force; on NO_PATH the
        # vehicle has none in force, and only these remain
        ents += [draw.replan(t, pid, xy) for pid, xy in self._replans]
        if m.status != self._path_status:
            level = LogLevel.Info if m.status == "OK" else LogLevel.Warning
            text = f"path {m.path_id}: {m.status}" + (f" ({m.reason})" if m.reason else "")
            text += f" [{m.strategy}]" if m.strategy else ""
            out.append(_event(t, level, service, text))
            self._path_status = m.status
        out.append(_replace_all(PLANNER_PATH, t, ents))
        return out

    # -- the network and the run -------------------------------------------------------------
    def _link_stats(self, service: str, m: LinkStats) -> list[ViewMessage]:
        self._links.see(m)
        rows: list[JsonValue] = [_link_columns(row) for row in self._links.rows()]
        return [_json(series.LINKS, {"t": m.stamp, "links": rows})]

    def _run_end(self, service: str, m: RunEnd) -> list[ViewMessage]:
        text = f"run ended at t={m.stamp:.2f} s: {m.reason} ({m.ticks} ticks)"
        return [
            _json(series.RUN_END, {"t": m.stamp, "reason": m.reason, "ticks": m.ticks}),
            _event(m.stamp, LogLevel.Info, service, text),
        ]


def vehicle_topic(vehicle: str, topic: str) -> str:
    """A fleet vehicle's own topic: the single vehicle's, under its id (/auv2/vehicle/pose)."""
    return f"/{vehicle}{topic}"


def _under(vehicle: str, vm: ViewMessage) -> ViewMessage:
    """A fleet vehicle's view message on its own topic (/auv2/...), unless it is the run's."""
    if vm.topic in RUN_TOPICS:
        return vm
    return dataclasses.replace(vm, topic=vehicle_topic(vehicle, vm.topic))


def _proto(topic: str, msg: Any) -> ViewMessage:
    """A foxglove-sdk typed message (any class with get_schema and encode) as a ViewMessage."""
    s = msg.get_schema()
    return ViewMessage(topic, s.name, s.encoding, s.data, "protobuf", msg.encode())


def _json(s: series.JsonSeries, values: Mapping[str, JsonValue]) -> ViewMessage:
    return ViewMessage(s.topic, s.title, "jsonschema", s.schema, "json", s.encode(values))


def _replace_all(topic: str, t: float, entities: list[SceneEntity]) -> ViewMessage:
    """A SceneUpdate that clears its topic and draws `entities`: complete in itself."""
    clear = SceneEntityDeletion(timestamp=stamp(t), type=SceneEntityDeletionType.All)
    return _proto(topic, SceneUpdate(deletions=[clear], entities=entities))


def _motion(m: TruthState | StateEstimate) -> dict[str, float]:
    """The series.MOTION fields of a truth or an estimate."""
    return {
        "t": m.stamp,
        "x_m": m.x,
        "y_m": m.y,
        "theta_rad": m.theta,
        "v_mps": m.v,
        "w_radps": m.w,
    }


def _pose(t: float, x: float, y: float, theta: float) -> PoseInFrame:
    return PoseInFrame(timestamp=stamp(t), frame_id=WORLD, pose=yaw_pose(x, y, theta))


def _transform(child: str, t: float, x: float, y: float, theta: float) -> FrameTransform:
    return FrameTransform(
        timestamp=stamp(t),
        parent_frame_id=WORLD,
        child_frame_id=child,
        translation=Vector3(x=x, y=y, z=0.0),
        rotation=yaw_quaternion(theta),
    )


def _trail(topic: str, trail: Trail, t: float, x: float, y: float, th: float) -> list[ViewMessage]:
    """The whole trail, when this pose was kept and the trail is due to be sent again."""
    if not (trail.add(x, y, th) and trail.due(t)):
        return []
    return [_proto(topic, PosesInFrame(timestamp=stamp(t), frame_id=WORLD, poses=trail.poses))]


def _errors(scored: list[Scored]) -> list[ViewMessage]:
    return [_json(series.ESTIMATE_ERROR, s._asdict()) for s in scored]


def _link_columns(row: LinkRow) -> JsonObject:
    """A link's row of /links (series.LINK_FIELDS): the sender's counters, modelled delays and
    loss fraction, the receiver's measured delays, each part once it was heard."""
    out: dict[str, JsonValue] = {"link": row.link}
    if (c := row.counters) is not None:
        out.update(c.counts(), loss_fraction=dropped(c) / c.sent if c.sent else 0.0)
    if (d := row.measured) is not None:
        out.update(
            measured_p50_s=d.delay_p50, measured_p95_s=d.delay_p95, measured_max_s=d.delay_max
        )
    return out


def _event(t: float, level: LogLevel, name: str, text: str) -> ViewMessage:
    return _proto(EVENTS, Log(timestamp=stamp(t), level=level, message=text, name=name))
