"""The Foxglove view (services/foxglove/view.py): pure translation, checked against hand
computations and the scenario, every message decoded with only its own schema."""

from __future__ import annotations

import json
import math
from typing import Any

import numpy as np
import pytest
from helpers.foxglove_view import REPO, decode, short_run, view_all

from common.config.scenario import Scenario, load_scenario
from common.messages import (
    Detection,
    LinkCounters,
    LinkStats,
    MeasuredDelay,
    ObstacleDetections,
    ObstacleTracks,
    PathMsg,
    RunEnd,
    StateEstimate,
    Tick,
    Track,
    TruthState,
    VehicleMode,
    VehicleStatus,
    VelocityCommand,
)
from common.messages import replace as replace_field
from services.foxglove import series
from services.foxglove import view as v
from services.foxglove.view import FoxgloveView, ViewMessage


@pytest.fixture(scope="module")
def scenario() -> Scenario:
    s, _ = load_scenario(REPO / "configs" / "default.toml")
    return s


def _one(msgs: list[ViewMessage], topic: str) -> dict[str, Any]:
    hits = [m for m in msgs if m.topic == topic]
    assert len(hits) == 1, f"{topic}: {len(hits)} messages in {[m.topic for m in msgs]}"
    return decode(hits[0])


def _entities(update: dict[str, Any]) -> dict[str, dict[str, Any]]:
    return {e["id"]: e for e in update["entities"]}


def _xy(line: dict[str, Any]) -> np.ndarray:
    return np.array([(p["x"], p["y"]) for p in line["points"]])


def _truth(t: float, x: float, y: float = 20.0, theta: float = 0.0) -> TruthState:
    return TruthState(stamp=t, x=x, y=y, theta=theta, v=1.5, w=0.0)


def _estimate(t: float, x: float, y: float, cov_diag: tuple[float, ...]) -> StateEstimate:
    cov = np.diag(cov_diag).ravel().tolist()
    return StateEstimate(stamp=t, x=x, y=y, theta=0.1, v=1.4, w=0.0, covariance=tuple(cov))


def test_static_draws_the_area_start_goal_and_every_static_obstacle(scenario: Scenario) -> None:
    msgs = FoxgloveView(scenario).static()
    scene = _one(msgs, v.SCENE_STATIC)
    assert [d["type"] for d in scene["deletions"]] == [1]  # clears the topic first (All)
    ents = _entities(scene)
    w = scenario.world
    ids = {f"obstacle/{c.id}" for c in w.circles} | {f"obstacle/{p.id}" for p in w.polygons}
    assert set(ents) == {"area", "start", "goal"} | ids
    assert all(e["frame_id"] == "world" for e in ents.values())
    a = w.area
    corners = {(a.x_min_m, a.y_min_m), (a.x_max_m, a.y_min_m), (a.x_max_m, a.y_max_m)}
    corners.add((a.x_min_m, a.y_max_m))
    area = ents["area"]["lines"][0]
    assert area["type"] == 1 and {tuple(p) for p in _xy(area)} == corners  # a closed loop
    for c in w.circles:
        cyl = ents[f"obstacle/{c.id}"]["cylinders"][0]
        assert cyl["size"]["x"] == pytest.approx(2 * c.radius_m)
        assert (cyl["pose"]["position"]["x"], cyl["pose"]["position"]["y"]) == (c.x_m, c.y_m)
        assert cyl["bottom_scale"] == cyl["top_scale"] == 1.0  # 0 would draw nothing
    for p in w.polygons:
        outline = _xy(ents[f"obstacle/{p.id}"]["lines"][0])
        assert outline.ravel().tolist() == list(p.vertices_m)
    goal = _xy(ents["goal"]["lines"][0])
    r = np.hypot(goal[:, 0] - w.goal.x_m, goal[:, 1] - w.goal.y_m)
    assert r == pytest.approx(np.full(len(r), w.goal_tolerance_m))
    info = _one(msgs, "/run/info")
    assert (info["name"], info["vehicle"], info["controller"]) == ("demo", "auv1", "nurbs")


def test_a_truth_state_gives_the_true_pose_its_frame_and_the_goal_distance(
    scenario: Scenario,
) -> None:
    msgs = FoxgloveView(scenario).translate("vehicle", "truth", _truth(12.25, 30.0, 21.0, 2.5))
    pose = _one(msgs, v.POSE_TRUE)
    assert pose["timestamp"] == {"seconds": 12, "nanos": 250_000_000}
    assert pose["frame_id"] == "world"
    q = pose["pose"]["orientation"]
    assert (q["x"], q["y"]) == (0.0, 0.0)
    assert 2.0 * math.atan2(q["z"], q["w"]) == pytest.approx(2.5)
    assert (pose["pose"]["position"]["x"], pose["pose"]["position"]["y"]) == (30.0, 21.0)
    tf = _one(msgs, v.TF)
    assert (tf["parent_frame_id"], tf["child_frame_id"]) == ("world", "auv")
    plot = _one(msgs, "/plot/truth")
    assert plot["distance_to_goal_m"] == pytest.approx(math.hypot(95.0 - 30.0, 20.0 - 21.0))
    # obstacle 1 (centre 20, 20, radius 4) is the nearest: the hull is 0.5 m wide... or so the
    # scenario says; the hand-computed clearance uses its radius from the config
    r_v = scenario.vehicle.radius_m
    assert plot["clearance_m"] <= math.hypot(30.0 - 20.0, 21.0 - 20.0) - 4.0 - r_v + 1e-9


def test_moving_obstacles_are_where_their_trajectories_put_them_at_the_truth_stamp(
    scenario: Scenario,
) -> None:
    t = 10.0
    msgs = FoxgloveView(scenario).translate("vehicle", "truth", _truth(t, 30.0))
    ents = _entities(_one(msgs, v.SCENE_MOVING))
    assert set(ents) == {"moving/10", "moving/11"}
    # obstacle 10 of default.toml: a line from (40, 34) at (0, -0.5) m/s
    p = ents["moving/10"]["cylinders"][0]["pose"]["position"]
    assert (p["x"], p["y"]) == pytest.approx((40.0, 34.0 - 0.5 * t))
    # obstacle 11: (89, 4) + (0, 0.4) t + 3 sin(2 pi 0.05 t) n, n the left normal of (0, 1)
    q = ents["moving/11"]["cylinders"][0]["pose"]["position"]
    s = 3.0 * math.sin(2 * math.pi * 0.05 * t)
    assert (q["x"], q["y"]) == pytest.approx((89.0 - s, 4.0 + 0.4 * t))
    assert ents["moving/10"]["timestamp"] == {"seconds": 10, "nanos": 0}


def test_a_track_draws_its_radius_and_its_2_sigma_hull(scenario: Scenario) -> None:
    cov = np.eye(6) * 0.01
    cov[0, 0], cov[1, 1], cov[0, 1], cov[1, 0] = 0.25, 0.09, 0.1, 0.1  # correlated x, y
    track = Track(
        id=10, x=40.0, y=30.0, vx=0.0, vy=-0.5, ax=0.0, ay=0.0, radius=1.5,
        covariance=tuple(cov.ravel().tolist()),
    )  # fmt: skip
    msgs = FoxgloveView(scenario).translate(
        "estimator", "tracks", ObstacleTracks(stamp=3.0, tracks=(track,))
    )
    ent = _entities(_one(msgs, v.SCENE_TRACKS))["track/10"]
    assert ent["cylinders"][0]["size"]["x"] == pytest.approx(3.0)
    hull = _xy(ent["lines"][0]) - [40.0, 30.0]
    # every hull point lies 2 sigma + radius out along its principal axis: in the frame of
    # cov's eigenvectors the points satisfy (u / a)^2 + (w / b)^2 = 1, a, b = 2 sqrt(l) + r
    lam, vec = np.linalg.eigh(cov[:2, :2])
    a, b = 2.0 * np.sqrt(lam) + 1.5
    u = hull @ vec
    assert (u[:, 0] / a) ** 2 + (u[:, 1] / b) ** 2 == pytest.approx(np.ones(len(u)))
    arrow = ent["arrows"][0]
    assert arrow["shaft_length"] + arrow["head_length"] == pytest.approx(0.5 * 2.0)  # 2 s ahead
    plot = _one(msgs, "/plot/tracks")
    assert plot["n_tracks"] == 1 and plot["max_std_xy_m"] == pytest.approx(0.5)
    # a new message replaces the old tracks: the topic is cleared first
    assert [d["type"] for d in _one(msgs, v.SCENE_TRACKS)["deletions"]] == [1]


def _path(pid: int, status: str = "OK", reason: str = "") -> PathMsg:
    ctrl = (5.0, 20.0, 20.0, 30.0, 40.0, 10.0, 60.0 + pid, 20.0)
    if status == "NO_PATH":
        return PathMsg(
            stamp=pid, path_id=pid, status="NO_PATH", reason=reason, degree=2,
            control_points=(), weights=(), knots=(), waypoints=(), length=0.0, f_l=0.0,
            max_curvature=0.0, v_ref=0.0,
        )  # fmt: skip
    return PathMsg(
        stamp=pid, path_id=pid, status="OK", reason=reason, degree=2, control_points=ctrl,
        weights=(1.0, 1.0, 1.0, 1.0), knots=(0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0),
        waypoints=(5.0, 20.0, 60.0, 20.0), length=60.0, f_l=1.1, max_curvature=0.1, v_ref=1.5,
    )  # fmt: skip


def test_the_path_in_force_its_replans_and_a_no_path(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    first = view.translate("planner", "path", _path(1))
    ents = _entities(_one(first, v.PLANNER_PATH))
    curve, polygon = (_xy(line) for line in ents["path"]["lines"])
    # a clamped NURBS starts and ends on its end control points
    assert curve[0] == pytest.approx([5.0, 20.0]) and curve[-1] == pytest.approx([61.0, 20.0])
    assert polygon.ravel().tolist() == list(_path(1).control_points)
    assert len(curve) == v.PATH_SAMPLES
    second = view.translate("planner", "path", _path(2))
    ents = _entities(_one(second, v.PLANNER_PATH))
    assert set(ents) == {"path", "replan/1", "replan/2"}
    assert _xy(ents["path"]["lines"][0])[-1] == pytest.approx([62.0, 20.0])
    assert _one(second, "/plot/path")["replans"] == 2
    assert not [m for m in second if m.topic == v.EVENTS]  # OK -> OK is no event
    blocked = view.translate("planner", "path", _path(3, "NO_PATH", "goal enclosed"))
    ents = _entities(_one(blocked, v.PLANNER_PATH))
    assert set(ents) == {"replan/1", "replan/2"}  # no path in force, earlier ones remain
    event = _one(blocked, v.EVENTS)
    assert event["level"] == 3 and "NO_PATH (goal enclosed)" in event["message"]  # Warning
    assert _one(blocked, "/plot/path")["ok"] == 0


def test_a_path_shows_the_strategy_that_made_it_and_those_rejected(scenario: Scenario) -> None:
    # the plan's reason codes (services/planner/reasons.py), as `tidelink monitor` shows them
    view = FoxgloveView(scenario)
    made = replace_field(_path(1), strategy="turned_first", rejected=("searched",))
    msgs = view.translate("planner", "path", made)
    plot = _one(msgs, "/plot/path")
    assert (plot["strategy"], plot["rejected"]) == ("turned_first", ["searched"])
    assert "[turned_first]" in _one(msgs, v.EVENTS)["message"]
    held = replace_field(
        _path(2, "NO_PATH", "no way out"), strategy="stuck", rejected=("searched", "turned_first")
    )
    plot = _one(view.translate("planner", "path", held), "/plot/path")
    assert (plot["strategy"], plot["rejected"]) == ("stuck", ["searched", "turned_first"])
    # a path from an older planner has no codes: empty, and the schema still holds
    plot = _one(view.translate("planner", "path", _path(3)), "/plot/path")
    assert (plot["strategy"], plot["rejected"]) == ("", [])
    schema = json.loads(series.PATH.schema)
    assert {"strategy", "rejected"} <= set(schema["required"])
    assert schema["properties"]["rejected"] == {"type": "array", "items": {"type": "string"}}


def test_replans_kept_are_bounded(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    for pid in range(1, v.MAX_REPLANS + 6):
        msgs = view.translate("planner", "path", _path(pid))
    ids = set(_entities(_one(msgs, v.PLANNER_PATH)))
    assert len(ids) == v.MAX_REPLANS + 1 and "replan/1" not in ids and "path" in ids


def test_estimate_error_is_measured_against_the_truth_at_its_stamp(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    early = view.translate("estimator", "state", _estimate(-0.5, 10.0, 20.0, (0.04,) * 5))
    assert not [m for m in early if m.topic == "/plot/estimate_error"]  # no truth yet
    scored = []
    for i in range(11):  # x = 5 + t; the early estimate is older than all of it: never scored
        scored += view.translate("vehicle", "truth", _truth(i * 0.1, 5.0 + i * 0.1))
    assert not [m for m in scored if m.topic == "/plot/estimate_error"]
    msgs = view.translate("estimator", "state", _estimate(0.55, 5.55 + 0.3, 20.4, (0.09,) * 5))
    assert _one(msgs, "/plot/estimate")["std_x_m"] == pytest.approx(0.3)
    error = _one(msgs, "/plot/estimate_error")
    assert error["t"] == 0.55 and error["error_m"] == pytest.approx(0.5)  # (0.3, 0.4) off
    assert error["heading_error_rad"] == pytest.approx(0.1)
    # an estimate stamped ahead of the truth waits for it
    ahead = view.translate("estimator", "state", _estimate(1.05, 6.05, 20.0, (0.09,) * 5))
    assert not [m for m in ahead if m.topic == "/plot/estimate_error"]
    later = view.translate("vehicle", "truth", _truth(1.1, 6.1))
    assert _one(later, "/plot/estimate_error")["error_m"] == pytest.approx(0.0, abs=1e-12)
    ell = _xy(_entities(_one(msgs, v.SCENE_ESTIMATE))["estimate"]["lines"][0])
    r = np.hypot(ell[:, 0] - 5.85, ell[:, 1] - 20.4)
    assert r == pytest.approx(np.full(len(r), 0.6))  # 2 sigma of an isotropic 0.3 m
    assert _one(msgs, v.POSE_EST)["pose"]["position"]["x"] == pytest.approx(5.85)


def test_mode_changes_are_events_and_modes_are_plottable(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)

    def status(t: float, mode: VehicleMode) -> list[ViewMessage]:
        msg = VehicleStatus(
            stamp=t, mode=mode, mode_since=t, v_applied=1.0, w_applied=0.0, command_age=0.2,
            commands_applied=3, commands_rejected=1, commands_clamped=0,
        )  # fmt: skip
        return view.translate("vehicle", "status", msg)

    modes: tuple[VehicleMode, ...] = ("RUN", "RUN", "HOLD", "FAILSAFE", "RUN")
    events = [m for t, mode in enumerate(modes)
              for m in status(t, mode) if m.topic == v.EVENTS]  # fmt: skip
    texts = [decode(m)["message"] for m in events]
    assert len(texts) == 4 and "RUN -> HOLD" in texts[1] and "FAILSAFE -> RUN" in texts[3]
    plot = _one(status(9.0, "FAILSAFE"), "/plot/vehicle")
    assert (plot["mode"], plot["mode_code"], plot["command_age_s"]) == ("FAILSAFE", 3, 0.2)
    cmd = _one(
        view.translate("planner", "cmd", VelocityCommand(stamp=1.0, v=1.2, w=-0.1, path_id=4)),
        "/plot/cmd",
    )
    assert (cmd["v_mps"], cmd["w_radps"], cmd["path_id"]) == (1.2, -0.1, 4)


def _counters(link: str, sent: int, lost: int) -> LinkCounters:
    return LinkCounters(
        link=link, sent=sent, delivered=sent - lost, dropped_loss=lost, dropped_outage=0,
        dropped_queue=0, duplicated=0, delay_p50=0.05, delay_p95=0.08, delay_p99=0.09,
    )  # fmt: skip


def test_link_stats_of_senders_and_receivers_in_one_table(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    # the planner sends cmd and receives state; the vehicle receives cmd
    measured = MeasuredDelay(
        link="planner/cmd->vehicle", delivered=19, delay_p50=0.06, delay_p95=0.1, delay_max=0.2
    )
    planner = LinkStats(
        stamp=1.0,
        links=(_counters("planner/cmd->vehicle", 20, 1),),
        measured=(replace_field(measured, link="estimator/state->planner"),),
    )
    view.translate("planner", "stats", planner)
    view.translate("vehicle", "stats", LinkStats(stamp=1.0, links=(), measured=(measured,)))
    estimator = LinkStats(stamp=2.0, links=(_counters("estimator/state->planner", 40, 4),))
    msgs = view.translate("estimator", "stats", estimator)
    rows = {r["link"]: r for r in _one(msgs, "/links")["links"]}
    assert list(rows) == ["estimator/state->planner", "planner/cmd->vehicle"]  # sorted
    cmd, state = rows["planner/cmd->vehicle"], rows["estimator/state->planner"]
    assert cmd["loss_fraction"] == pytest.approx(0.05) and cmd["measured_p95_s"] == 0.1
    assert (cmd["sent"], cmd["delay_p95_s"], cmd["measured_max_s"]) == (20, 0.08, 0.2)
    assert state["loss_fraction"] == pytest.approx(0.1) and state["measured_p50_s"] == 0.06


def test_run_end_and_detections(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    end = view.translate("runtime", "end", RunEnd(stamp=61.5, reason="goal", ticks=1230))
    assert _one(end, "/run/end") == {"t": 61.5, "reason": "goal", "ticks": 1230}
    assert "goal" in _one(end, v.EVENTS)["message"]
    det = Detection(id=3, x=34.0, y=32.0, radius=4.4, std_xy=0.3, std_radius=0.2)
    scan = view.translate("sensor", "obstacles", ObstacleDetections(stamp=2.0, detections=(det,)))
    ring = _xy(_entities(_one(scan, v.SCENE_DETECTIONS))["detection/3"]["lines"][0])
    assert np.hypot(ring[:, 0] - 34.0, ring[:, 1] - 32.0) == pytest.approx(np.full(24, 4.4))
    # a clock message is not part of the view
    tick = Tick(stamp=0.0, tick=1, time_us=0)
    assert view.translate("runtime", "tick", tick) == []


def test_trails_are_thinned_and_sent_at_most_twice_a_second(scenario: Scenario) -> None:
    view = FoxgloveView(scenario)
    sent = []
    for i in range(200):  # 10 s at 20 Hz, 0.05 m apart
        for m in view.translate("vehicle", "truth", _truth(i * 0.05, 5.0 + i * 0.05)):
            if m.topic == v.TRAIL_TRUE:
                sent.append(decode(m))
    assert 15 <= len(sent) <= 21  # every 0.5 s of mission time
    last = sent[-1]["poses"]
    xs = [p["position"]["x"] for p in last]
    assert np.diff(xs) == pytest.approx(np.full(len(xs) - 1, 0.25), abs=0.051)  # one per 0.25 m
    assert xs[0] == 5.0 and len(xs) == pytest.approx(10.0 / 0.25, abs=2)


@pytest.fixture(scope="module")
def run_view() -> list[ViewMessage]:
    return view_all(*short_run())


def test_a_real_run_translates_into_messages_each_decodable_with_its_schema(
    run_view: list[ViewMessage],
) -> None:
    topics = {m.topic for m in run_view}
    assert topics >= {
        v.SCENE_STATIC, v.SCENE_MOVING, v.SCENE_TRACKS, v.SCENE_DETECTIONS, v.SCENE_ESTIMATE,
        v.PLANNER_PATH, v.POSE_TRUE, v.POSE_EST, v.TRAIL_TRUE, v.TRAIL_EST, v.NAV_FIX, v.TF,
        v.EVENTS, "/plot/cmd", "/plot/vehicle", "/plot/truth", "/plot/estimate", "/plot/path",
        "/plot/estimate_error",
        "/plot/tracks", "/links", "/run/info",
    }  # fmt: skip
    schema_of: dict[str, tuple[str, str, bytes, str]] = {}
    for m in run_view:
        decode(m)  # raises on bytes that do not match the schema
        key = (m.schema_name, m.schema_encoding, m.schema, m.message_encoding)
        assert schema_of.setdefault(m.topic, key) == key, f"{m.topic} changed its schema"
    errors = [decode(m)["error_m"] for m in run_view if m.topic == "/plot/estimate_error"]
    # the default sensor has 0.5 m position noise: the filtered estimate stays well inside 3 m
    assert len(errors) > 50 and max(errors) < 3.0


def test_a_fleets_vehicles_each_have_their_topics_frames_start_and_goal() -> None:
    fleet, _ = load_scenario(REPO / "configs" / "fleet4.toml")
    members = dict(fleet.members)
    view = FoxgloveView(fleet)
    chart = _entities(_one(view.static(), v.SCENE_STATIC))
    assert "start" not in chart and "goal" not in chart  # the base scenario's are nobody's
    for vid, m in members.items():
        g = m.world.goal
        assert [t["text"] for t in chart[f"{vid}/goal"]["texts"]] == [f"{vid} goal"]
        assert _xy(chart[f"{vid}/goal"]["lines"][0]).mean(axis=0) == pytest.approx(
            (g.x_m, g.y_m), abs=0.05
        )
    one = view.translate("auv1.vehicle", "truth", _truth(3.0, 30.0))
    two = view.translate("auv2.vehicle", "truth", _truth(3.0, 60.0))
    assert _one(one, "/auv1" + v.POSE_TRUE)["pose"]["position"]["x"] == 30.0
    assert _one(two, "/auv2" + v.POSE_TRUE)["pose"]["position"]["x"] == 60.0
    assert _one(two, v.TF)["child_frame_id"] == "auv2"  # one /tf, a frame per vehicle
    g2 = members["auv2"].world.goal
    assert _one(two, "/auv2/plot/truth")["distance_to_goal_m"] == pytest.approx(
        math.hypot(g2.x_m - 60.0, g2.y_m - 20.0)
    )
    # the moving obstacles are the run's: drawn once, at the first vehicle's truth
    assert [m.topic for m in one].count(v.SCENE_MOVING) == 1
    assert v.SCENE_MOVING not in [m.topic for m in two]
    path = view.translate("auv3.planner", "path", _path(2))
    assert {m.topic for m in path} >= {"/auv3" + v.PLANNER_PATH, v.EVENTS}
    assert decode([m for m in path if m.topic == v.EVENTS][0])["name"] == "auv3.planner"
    # the same path again as auv3's intent (each second, for the others) is no replan
    assert view.translate("auv3.planner", "intent", _path(2)) == []
    # nor is a truth state again as auv1's hull (before the others' scans) a new pose
    assert view.translate("auv1.vehicle", "hull", _truth(3.5, 31.0)) == []
