"""RunState, the monitor's picture of a run: events, alarms, late-join facts, JSON output."""

from __future__ import annotations

import io
import json
import math

import pytest
from helpers.samples import one_of_each

from common.bus import RawFrame
from common.bus.watcher import END_GRACE_S, watched
from common.config.scenario import load_scenario
from common.messages import (
    LinkCounters,
    LinkStats,
    MeasuredDelay,
    PathMsg,
    RunEnd,
    StateEstimate,
    TruthState,
    VehicleStatus,
    WireError,
    encode_watch,
    replace,
)
from services.monitor.state import RunState
from services.monitor.views import JsonLinesView

SAMPLES = {type(m).__name__: m for m in one_of_each()}


def _state() -> RunState:
    s = RunState("demo", "auv1", stale_s=1.0)
    s.scenario, _ = load_scenario("configs/default.toml")
    return s


def _status(t: float, mode: str, since: float) -> VehicleStatus:
    base = SAMPLES["VehicleStatus"]
    assert isinstance(base, VehicleStatus)
    return replace(base, stamp=t, mode=mode, mode_since=since)  # type: ignore[return-value]


def test_a_late_joiner_learns_the_mode_and_when_it_last_changed_from_one_status() -> None:
    s = _state()
    s.see("vehicle", "status", _status(30.0, "HOLD", 27.5), wall=100.0)
    (ev,) = s.take_events()
    assert ev.kind == "mode" and ev.data == {"mode": "HOLD", "since": 27.5}
    s.see("vehicle", "status", _status(30.1, "HOLD", 27.5), wall=100.1)
    assert s.take_events() == []  # no change, no event
    s.see("vehicle", "status", _status(30.2, "FAILSAFE", 30.2), wall=100.2)
    (ev,) = s.take_events()
    assert ev.data["from"] == "HOLD" and ev.data["mode"] == "FAILSAFE"
    assert "vehicle FAILSAFE" in s.alarms(now=100.2)


def test_the_path_in_force_is_the_newest_id_and_replans_are_counted_once() -> None:
    s = _state()
    p = SAMPLES["PathMsg"]
    assert isinstance(p, PathMsg)
    s.see("planner", "path", replace(p, path_id=3), wall=10.0)
    s.see("planner", "path", replace(p, path_id=2), wall=10.1)  # older, arriving late
    s.see("planner", "path", replace(p, path_id=3), wall=10.2)  # the same one again (latest)
    snap = s.snapshot(now=10.3)
    assert snap["path"]["path_id"] == 3
    assert snap["path"]["replans"] == 1  # two distinct paths seen
    no_path = replace(p, path_id=4, status="NO_PATH", reason="blocked")
    s.see("planner", "path", no_path, wall=11.0)
    assert "NO_PATH: blocked" in s.alarms(now=11.0)


def test_the_dashboard_shows_the_last_plans_strategy_and_the_plans_by_strategy() -> None:
    from rich.console import Console

    from services.monitor.views import _panel

    s = _state()
    p = SAMPLES["PathMsg"]
    assert isinstance(p, PathMsg)
    s.see("planner", "path", replace(p, path_id=1, strategy="searched"), wall=10.0)
    partway = replace(p, path_id=2, strategy="partway", rejected=("searched", "turned_first"))
    s.see("planner", "path", partway, wall=10.1)
    s.see("planner", "path", partway, wall=10.2)  # the same one again: counted once
    path = s.snapshot(now=10.3)["path"]
    assert (path["strategy"], path["rejected"]) == ("partway", ["searched", "turned_first"])
    assert path["strategies"] == {"partway": 1, "searched": 1}
    events = s.take_events()
    assert events[-1].text.endswith("[partway]") and events[-1].data["strategy"] == "partway"
    out = io.StringIO()
    Console(file=out, width=160).print(_panel(s.snapshot(now=10.3)))
    shown = out.getvalue()
    assert "by partway after searched, turned_first" in shown
    assert "plans by" in shown and "partway 1  searched 1" in shown


def test_estimate_error_compares_samples_close_in_time_only() -> None:
    s = _state()
    est = SAMPLES["StateEstimate"]
    assert isinstance(est, StateEstimate)
    truth = TruthState(stamp=5.0, x=10.0, y=0.0, theta=0.0, v=1.0, w=0.0)
    s.see("vehicle", "truth", truth, wall=1.0)
    s.see("estimator", "state", replace(est, stamp=9.0, x=13.0, y=4.0), wall=1.1)
    assert s.est_error_m is None  # 4 s apart: not comparable
    s.see("estimator", "state", replace(est, stamp=5.05, x=13.0, y=4.0), wall=1.2)
    assert s.est_error_m == pytest.approx(5.0)
    assert s.to_goal_m() is not None


def test_a_periodic_stream_goes_stale_but_an_event_stream_never_does() -> None:
    s = _state()
    truth = TruthState(stamp=0.0, x=0.0, y=0.0, theta=0.0, v=0.0, w=0.0)
    for i in range(5):
        s.see("vehicle", "truth", replace(truth, stamp=i * 0.1), wall=100.0 + i * 0.1)
    s.see("planner", "path", SAMPLES["PathMsg"], wall=100.0)
    assert s.alarms(now=100.5) == []
    assert s.alarms(now=102.0) == ["stream vehicle/truth stale"]
    raised = [e for e in s.take_events() if e.kind == "alarm"]
    assert [e.data["raised"] for e in raised] == [True]
    s.see("vehicle", "truth", replace(truth, stamp=2.0), wall=102.0)
    assert s.alarms(now=102.0) == []
    cleared = [e for e in s.take_events() if e.kind == "alarm"]
    assert cleared and cleared[-1].data == {"raised": False}


def test_liveliness_tells_up_gone_and_restarted_and_the_clock_ends_the_run() -> None:
    s = _state()
    s.liveliness("runtime", True, 1.0)
    s.liveliness("planner", True, 1.0)
    s.liveliness("planner", False, 2.0)
    assert "service planner gone" in s.alarms(now=2.0)
    s.liveliness("planner", True, 3.0)
    snap = s.snapshot(now=3.0)
    assert snap["services"]["planner"] == {"state": "restarted", "since": 3.0, "restarts": 1}
    assert not s.over(now=3.0)
    s.liveliness("runtime", False, 4.0)
    # the clock is gone; its RunEnd may still be in flight: over after the grace only
    assert not s.over(now=4.0 + END_GRACE_S / 2)
    assert s.over(now=4.0 + END_GRACE_S + 0.1)


def test_a_run_whose_copies_still_drain_after_its_clock_went_is_not_over_yet() -> None:
    # under load the tap's backlog of copies, and the RunEnd behind it, arrive seconds after
    # the clock's token vanished: the grace counts from the last frame heard
    s = _state()
    s.liveliness("runtime", True, 1.0)
    s.liveliness("runtime", False, 4.0)
    s.heard_at = 4.0 + END_GRACE_S  # a copy of the backlog, just now
    assert not s.over(now=4.0 + END_GRACE_S + 0.1)
    assert s.over(now=4.0 + 2 * END_GRACE_S + 0.1)


def test_run_end_and_link_stats_reach_the_snapshot_and_json_lines_are_strict_json() -> None:
    s = _state()
    link = LinkCounters(
        link="planner/cmd->vehicle",
        sent=10,
        delivered=7,
        dropped_loss=2,
        dropped_outage=1,
        dropped_queue=0,
        duplicated=0,
        delay_p50=0.05,
        delay_p95=0.08,
        delay_p99=0.09,
    )
    s.see("planner", "stats", LinkStats(stamp=1.0, links=(link,)), wall=1.0)
    s.see("runtime", "end", RunEnd(stamp=65.5, reason="goal", ticks=0), wall=2.0)
    s.view("").est_error_m = math.nan  # what a diverged filter could leave: must not break JSON
    out = io.StringIO()
    JsonLinesView(out).update([s], now=2.0)
    snap = json.loads(out.getvalue())
    assert snap["type"] == "update"
    assert snap["links"]["planner/cmd->vehicle"]["lost"] == 3
    assert snap["links"]["planner/cmd->vehicle"]["modelled_p95_s"] == 0.08
    measured = MeasuredDelay(
        link="planner/cmd->vehicle", delivered=7, delay_p50=0.06, delay_p95=0.1, delay_max=0.2
    )
    s.see("vehicle", "stats", LinkStats(stamp=1.0, links=(), measured=(measured,)), wall=1.0)
    row = s.snapshot(now=2.0)["links"]["planner/cmd->vehicle"]
    assert (row["sent"], row["measured_p50_s"], row["measured_p95_s"]) == (10, 0.06, 0.1)
    assert snap["end"] == {"reason": "goal", "t_end_s": 65.5, "ticks": 0}
    assert snap["est_error_m"] is None
    assert s.over(now=2.0)  # the RunEnd itself ends the run at once


def test_a_watched_frame_needs_a_watch_key_and_the_taps_attachment() -> None:
    payload = b"\x92\x03\x80"
    att = encode_watch(12.5, 7, b"routing")
    f = watched(RawFrame("tidelink/demo/auv1/watch/vehicle/truth", payload, att))
    assert (f.run, f.vehicle, f.service, f.stream, f.wall, f.n) == (
        "demo",
        "auv1",
        "vehicle",
        "truth",
        12.5,
        7,
    )
    assert f.attachment == b"routing"
    with pytest.raises(ValueError, match="not a tidelink watch"):
        watched(RawFrame("tidelink/demo/auv1/vehicle/truth", payload, att))
    with pytest.raises(WireError, match="without the tap's attachment"):
        watched(RawFrame("tidelink/demo/auv1/watch/vehicle/truth", payload, None))
    with pytest.raises(WireError, match="malformed watch attachment"):
        watched(RawFrame("tidelink/demo/auv1/watch/vehicle/truth", payload, b"\xc1junk"))


def test_a_monitor_without_a_router_fails_with_one_line_naming_the_endpoint(
    capsys: pytest.CaptureFixture[str],
) -> None:
    from common.runtime.processes.children import free_port
    from services.cli import main

    endpoint = f"tcp/127.0.0.1:{free_port()}"  # nobody listens there
    assert main(["monitor", "--connect", endpoint, "--json", "--no-wait"]) == 1
    err = capsys.readouterr().err
    assert f"cannot reach the router at {endpoint}" in err
    assert "Traceback" not in err


def test_a_fleets_vehicles_are_each_shown_apart_with_their_own_goal_mode_and_alarms() -> None:
    s = RunState("fleet4", "fleet", stale_s=1.0)
    s.scenario, _ = load_scenario("configs/fleet4.toml")
    goals = {vid: m.world.goal for vid, m in s.scenario.members}
    truth = SAMPLES["TruthState"]
    p = SAMPLES["PathMsg"]
    assert isinstance(truth, TruthState) and isinstance(p, PathMsg)
    # both vehicles at (50, 20): each is its own distance from its own goal
    for vid in ("auv1", "auv2"):
        s.see(f"{vid}.vehicle", "truth", replace(truth, stamp=5.0, x=50.0, y=20.0), wall=1.0)
        # its hull (the truth again, for the others' sonars) counts as a stream, not a pose
        s.see(f"{vid}.vehicle", "hull", replace(truth, stamp=5.0, x=0.0, y=0.0), wall=1.0)
    s.see("auv2.vehicle", "status", _status(5.0, "FAILSAFE", 4.0), wall=1.0)
    s.see("auv1.planner", "path", replace(p, path_id=7), wall=1.0)
    snap = s.snapshot(now=1.0)
    fleet = snap["vehicles"]
    assert set(fleet) == {"auv1", "auv2"}
    for vid, g in goals.items():
        if vid in fleet:
            assert fleet[vid]["to_goal_m"] == pytest.approx(math.hypot(50 - g.x_m, 20 - g.y_m))
    assert fleet["auv2"]["mode"] == "FAILSAFE" and fleet["auv1"]["mode"] is None
    assert fleet["auv1"]["path"]["path_id"] == 7 and fleet["auv2"]["path"] is None
    # nothing of one vehicle is shown as the run's own (there is none)
    assert snap["pose"] is None and snap["to_goal_m"] is None and snap["path"] is None
    assert "auv2 FAILSAFE" in snap["alarms"]
    texts = [ev.text for ev in s.take_events()]
    assert "auv2 mode FAILSAFE since t=4.00 s" in texts
    assert any(t.startswith("auv1 path 7 ") for t in texts)


def test_the_dashboard_shows_a_row_per_fleet_vehicle() -> None:
    from rich.console import Console

    from services.monitor.views import _panel

    s = RunState("fleet4", "fleet", stale_s=1.0)
    s.scenario, _ = load_scenario("configs/fleet4.toml")
    truth = SAMPLES["TruthState"]
    assert isinstance(truth, TruthState)
    for vid in ("auv1", "auv3"):
        s.see(f"{vid}.vehicle", "truth", replace(truth, stamp=5.0, x=50.0, y=20.0), wall=1.0)
    out = io.StringIO()
    Console(file=out, width=160).print(_panel(s.snapshot(now=1.0)))
    shown = out.getvalue()
    assert "auv1" in shown and "auv3" in shown and "to goal" in shown


def test_paths_are_never_stale_however_quickly_the_last_replans_came() -> None:
    s = _state()
    p = SAMPLES["PathMsg"]
    assert isinstance(p, PathMsg)
    for i in range(4):  # four replans within a second, then none: a path is no heartbeat
        s.see("planner", "path", replace(p, path_id=i + 1, stamp=i * 0.3), wall=100.0 + i * 0.3)
    assert s.alarms(now=130.0) == []


def test_services_leaving_once_every_vehicle_was_at_its_goal_raise_no_alarm() -> None:
    s = _state()
    assert s.scenario is not None
    g, truth = s.scenario.world.goal, SAMPLES["TruthState"]
    assert isinstance(truth, TruthState)
    s.liveliness("planner", True, 1.0)
    s.liveliness("planner", False, 2.0)  # mid-run: an alarm
    assert s.alarms(now=2.0) == ["service planner gone"]
    s.liveliness("planner", True, 3.0)
    s.see("vehicle", "truth", replace(truth, stamp=60.0, x=g.x_m - 0.5, y=g.y_m), wall=4.0)
    s.liveliness("planner", False, 5.0)  # the mission is over: its RunEnd is on its way
    assert s.ending() and s.alarms(now=5.0) == []


def test_a_fleet_is_ending_only_once_every_vehicle_was_at_its_goal() -> None:
    s = RunState("fleet4", "fleet", stale_s=1.0)
    s.scenario, _ = load_scenario("configs/fleet4.toml")
    truth = SAMPLES["TruthState"]
    assert isinstance(truth, TruthState)
    members = dict(s.scenario.members)
    for i, vid in enumerate(sorted(members)):
        assert not s.ending()
        g = members[vid].world.goal
        s.see(f"{vid}.vehicle", "truth", replace(truth, stamp=50.0 + i, x=g.x_m, y=g.y_m), wall=i)
    assert s.ending()
