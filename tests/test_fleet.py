"""Fleets: [[vehicles]] config, the fleet dataflow, seeing each other, intents, fleet metrics."""

from __future__ import annotations

import dataclasses
import math
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers.launch_proc import REPO, tidelink_check, tidelink_cli

from common.config.errors import ConfigError
from common.config.fleet import MAX_VEHICLES
from common.config.loader import read_scenario_toml
from common.config.network import profile_for
from common.config.planner import PlannerConfig
from common.config.scenario import Scenario, load_scenario, scenario_from_raw
from common.config.vehicle import VehicleConfig
from common.messages import PathMsg, StateEstimate, TruthState
from common.runtime.distributed.lockstep import run_lockstep
from common.runtime.model.core import Delivery
from common.runtime.model.inproc import run_inproc
from common.runtime.model.mission import load_mission
from common.world import World
from common.world.check import check_scenario
from services.launcher.launch import select_services
from services.launcher.plot import _of_type
from services.launcher.progress import MissionView
from services.mission.fleet import fleet_obstacle_ids
from services.mission.records import FleetMetrics
from services.planner.plan import PlanRequest, plan_path
from services.planner.replan import ReplanPolicy
from services.planner.result import Obstacles, Pose2D
from services.planner.safety.intent import FleetIntents, IntentObstacle
from services.sensor.core import SensorCore
from services.vehicle.core import VehicleCore

CONFIGS = REPO / "configs"
FLEET4 = CONFIGS / "fleet4.toml"
HEADON = CONFIGS / "fleet_headon.toml"
HEADON_SHORT = CONFIGS / "experiments" / "scenarios" / "headon_short.toml"


def _raw(path: Path = FLEET4) -> dict[str, Any]:
    return read_scenario_toml(path)


def _fleet(raw: dict[str, Any]) -> Scenario:
    return scenario_from_raw(raw, "fleet.toml", check=check_scenario)


# -- config ----------------------------------------------------------------------------------


def test_a_scenario_without_vehicles_is_the_single_auv() -> None:
    s, _ = load_scenario(CONFIGS / "default.toml")
    assert s.vehicles == () and s.members == ()
    assert load_mission(s).dataflow.names == ("estimator", "planner", "sensor", "vehicle")


def test_extends_merges_a_scenario_over_another() -> None:
    raw = _raw()
    base = read_scenario_toml(CONFIGS / "default.toml")
    assert raw["world"]["circles"] == base["world"]["circles"]  # inherited
    assert raw["run"]["name"] == "fleet4" and raw["run"]["seed"] == base["run"]["seed"]


def test_an_entry_overrides_its_sections_key_by_key() -> None:
    raw = _raw()
    raw["vehicles"][1]["planner"] = {"rho0_m": 2.0}
    raw["vehicles"][1]["vehicle"] = {"cruise_speed_mps": 1.2}
    s = _fleet(raw)
    one, two = s.members[0][1], s.members[1][1]
    assert two.planner.rho0_m == 2.0 and one.planner.rho0_m == s.planner.rho0_m
    # the keys the entry left out are the scenario's, not the dataclass defaults
    assert two.planner.resolution_m == s.planner.resolution_m == 0.5
    assert two.vehicle.cruise_speed_mps == 1.2 and two.vehicle.v_max_mps == s.vehicle.v_max_mps
    assert two.world.start.x_m == 92.0 and two.world.goal.x_m == 8.0
    assert two.world.circles == s.world.circles


@pytest.mark.parametrize(
    ("edit", "key", "words"),
    [
        (lambda v: v[0].update(colour="red"), "vehicles[0].colour", "unknown key"),
        (lambda v: v[1].update(id="auv1"), "vehicles[1].id", "used twice"),
        (lambda v: v[0].update(id="auv.1"), "vehicles[0].id", "letters, digits"),
        (lambda v: v[0].update(id="other"), "vehicles[0].id", "reserved"),
        (lambda v: v[2].pop("goal"), "vehicles[2].goal", "required"),
        (lambda v: v[1].update(planner={"rho0_m": -1.0}), "vehicles[1].planner.rho0_m", ""),
        (lambda v: v[3].update(start={"x_m": 500.0, "y_m": 5.0}), "vehicles[3].start", "area"),
        # inside circle 1 of the default field (20, 20, r 4)
        (lambda v: v[0].update(start={"x_m": 20.0, "y_m": 20.0}), "vehicles[0].start", "contact"),
        (lambda v: v[1].update(start={"x_m": 8.3, "y_m": 8.0}), "vehicles[1].start", "touch"),
        (lambda v: v.extend([dict(v[0], id=f"x{i}") for i in range(13)]), "vehicles", "at most"),
    ],
)
def test_a_bad_vehicle_entry_names_its_key(edit: Any, key: str, words: str) -> None:
    raw = _raw()
    edit(raw["vehicles"])
    with pytest.raises(ConfigError) as exc:
        _fleet(raw)
    assert exc.value.key == key, exc.value
    assert words in exc.value.problem
    assert MAX_VEHICLES == 16


def test_a_fleet_refuses_a_placement() -> None:
    raw = _raw()
    raw["placement"] = {"services": {"planner": "ship"}}
    raw["placement"]["stations"] = [{"name": "ship", "x_m": -100.0, "y_m": 20.0}]
    with pytest.raises(ConfigError) as exc:
        _fleet(raw)
    assert exc.value.key == "placement"


def test_tidelink_check_exits_2_on_a_bad_fleet(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text(
        FLEET4.read_text()
        .replace('id = "auv3"', 'id = "auv1"')
        .replace('extends = "default.toml"', f'extends = "{CONFIGS / "default.toml"}"')
    )
    res = tidelink_check(str(bad))
    assert res.returncode == 2, res.stderr
    assert "vehicles[2].id: 'auv1' is used twice" in res.stderr


# -- dataflow and links ----------------------------------------------------------------------


def test_the_fleet_dataflow_is_each_vehicles_plus_the_links_between_them() -> None:
    s = _fleet(_raw())
    flow = load_mission(s).dataflow
    assert len(flow.names) == 16 and "auv3.planner" in flow.names
    sensor = flow.service("auv2.sensor")
    assert {i.source for i in sensor.inputs} == {f"auv{k}.vehicle" for k in (1, 2, 3, 4)}
    planner = flow.service("auv2.planner")
    heard = {(i.source, i.stream) for i in planner.inputs}
    assert ("auv1.planner", "intent") in heard and ("auv4.planner", "pose") in heard
    assert ("auv1.planner", "path") not in heard  # the path in force, re-sent: "intent"
    assert ("auv2.estimator", "state") in heard and ("auv2.planner", "path") not in heard
    assert ("auv4.estimator", "state") not in heard
    assert flow.service("auv2.vehicle").inputs[0].source == "auv2.planner"
    links = {lk.name for lk in flow.links}
    assert "auv1.planner/intent->auv2.planner" in links
    assert "auv1.vehicle/hull->auv2.sensor" in links
    assert "auv1.vehicle/truth->auv2.sensor" not in links  # every step: its own sensor only


def test_a_profile_without_vehicle_ids_covers_every_vehicle_and_a_qualified_one_wins() -> None:
    raw = {
        "default": {"delay_s": 0.05},
        "links": [
            {"link": "planner/path->planner", "profile": {"delay_s": 0.5}},
            {"link": "auv2.planner/path->auv1.planner", "profile": {"delay_s": 0.9}},
            {"link": "planner/cmd->*", "profile": {"delay_s": 0.2}},
            {"link": "other.planner/pose->planner", "profile": {"delay_s": 0.7}},
            {"link": "estimator/state->planner", "profile": {"delay_s": 0.1}},
            {"link": "planner/pose->planner", "profile": {"delay_s": 0.3}},
        ],
    }
    net = scenario_from_raw({"network": raw}).network
    assert profile_for(net, "auv3.planner/path->auv1.planner").delay_s == 0.5
    assert profile_for(net, "auv2.planner/path->auv1.planner").delay_s == 0.9
    assert profile_for(net, "auv4.planner/cmd->auv4.vehicle").delay_s == 0.2
    assert profile_for(net, "planner/cmd->vehicle").delay_s == 0.2
    assert profile_for(net, "auv1.sensor/nav->auv1.estimator").delay_s == 0.05
    # 'other.' names only the links from another vehicle
    assert profile_for(net, "auv2.planner/pose->auv1.planner").delay_s == 0.7
    assert profile_for(net, "auv1.estimator/state->auv1.planner").delay_s == 0.1
    assert profile_for(net, "estimator/state->planner").delay_s == 0.1


def test_a_vehicle_sends_its_hull_only_at_the_last_step_before_each_scan() -> None:
    core = VehicleCore(
        VehicleConfig(period_s=0.05),
        (0.0, 0.0, 0.0),
        hull_scans_s=((0.5, 0.0), (0.3, 0.0), (0.5, 0.12)),
    )
    sent = [k for k in range(41) if any(e.stream == "hull" for e in core.step(k * 0.05))]
    # scans at 0.3, 0.5, 0.6, 0.9, 1.0, ... and at 0.12, 0.62, ...: the step before each (a
    # scan at a step's own time takes the step before: nothing is delivered in the tick it
    # is sent)
    scans = [m * p for p in (0.5, 0.3) for m in range(1, 8)] + [0.12 + 0.5 * m for m in range(4)]
    assert sent == sorted({math.ceil(round(sc / 0.05, 6)) - 1 for sc in scans if sc <= 2.05})
    single = VehicleCore(VehicleConfig(), (0.0, 0.0, 0.0))
    assert [e.stream for e in single.step(0.05)] == ["truth", "status"]  # no fleet: no hull


@pytest.mark.deterministic
@pytest.mark.parametrize("phase_s", [0.0, 0.035])
def test_each_sonar_scan_holds_the_newest_truth_of_the_other_hull(phase_s: float) -> None:
    raw = _raw(HEADON)
    raw["run"]["max_time_s"] = 6.0
    raw["vehicles"][0]["sensor"] = {"obstacle_rate_hz": 5.0}  # the two sonars scan apart
    raw["vehicles"][1]["phase_s"] = phase_s  # and, but for 0, step apart
    s = _fleet(raw)
    flow = load_mission(s).dataflow
    for name in ("sensor", "estimator", "planner", "vehicle"):
        one, two = flow.service(f"auv1.{name}"), flow.service(f"auv2.{name}")
        assert one.period_s is not None
        assert two.offset_s == pytest.approx((one.offset_s + phase_s) % one.period_s)
    rec = run_inproc(s).record
    members = dict(s.members)
    for me, other in (("auv1", "auv2"), ("auv2", "auv1")):
        cfg = members[me].sensor
        first = flow.service(f"{me}.sensor").offset_s
        # up to a vehicle step past the end: the last steps send for scans the run never saw
        scans = np.arange(first, 6.05 + 1e-9, cfg.scan_every * cfg.period_s)
        truth = [m.stamp for m in rec.stream(f"{other}.vehicle", "truth")]
        hull = [m.stamp for m in rec.stream(f"{other}.vehicle", "hull")]
        newest = {max(t for t in truth if t < sc - 1e-9) for sc in scans if sc > truth[0]}
        # the sonar scans there (its first scan, with no truth yet, takes nothing)
        seen = rec.stream(f"{me}.sensor", "obstacles")
        assert len(seen) == sum(1 for sc in scans if first < sc <= s.run.max_time_s + 1e-9)
        # every hull a scan will take is sent, and none else
        assert set(hull) == newest and len(hull) < len(truth) / 3
        # the run's plot draws the truth once, not again from the hull
        assert [m.stamp for m in _of_type(rec, TruthState, other)] == truth


@pytest.mark.slow
def test_vehicles_out_of_phase_run_the_same_in_lockstep_as_inproc(tmp_path: Path) -> None:
    # 8 service processes and the clock; auv2 steps 35 ms into every period (its sonar's
    # scans, and auv1's hulls for them, with it)
    raw = _raw(HEADON)
    raw["run"]["max_time_s"] = 8.0
    raw["vehicles"][1]["phase_s"] = 0.035
    s = _fleet(raw)
    ref = run_inproc(s)
    got = run_lockstep(s, raw, tmp_path / "logs")
    assert got.metrics.trajectory_sha256 == ref.metrics.trajectory_sha256
    for key in (("auv1.vehicle", "hull"), ("auv2.sensor", "obstacles"), ("auv2.planner", "path")):
        assert got.record.stream(*key) == ref.record.stream(*key), key
    assert ref.record.stream("auv1.vehicle", "hull")  # sent, for auv2's scans


def test_a_vehicles_phase_must_be_a_number_of_seconds() -> None:
    raw = _raw(HEADON)
    raw["vehicles"][1]["phase_s"] = -0.01
    with pytest.raises(ConfigError, match=r"vehicles\[1\]\.phase_s.*>= 0"):
        _fleet(raw)


def _truth(source: str, x: float, y: float, theta: float = 0.0, v: float = 1.0) -> Delivery:
    msg = TruthState(source=source, seq=1, stamp=1.0, x=x, y=y, theta=theta, v=v, w=0.0)
    return Delivery(source=source, stream="truth", msg=msg, t=1.0)


def test_a_sonar_sees_the_other_vehicles_and_takes_its_pose_only_from_its_own() -> None:
    s = _fleet(_raw())
    ids = fleet_obstacle_ids(s)
    assert min(ids.values()) > max(World(s.world).obstacle_ids)
    m = s.members[0][1]
    core = SensorCore(
        dataclasses.replace(m.sensor, p_detect=1.0, det_fov_half_angle_rad=np.pi),
        World(m.world),
        np.random.default_rng(1),
        own="auv1.vehicle",
        others={"auv2.vehicle": (ids["auv2"], 0.5)},
    )
    core.deliver(_truth("auv1.vehicle", 10.0, 10.0))
    core.deliver(_truth("auv2.vehicle", 14.0, 10.0, theta=np.pi))
    core.deliver(_truth("auv9.vehicle", 50.0, 10.0))  # wired to no one: ignored
    scans = [e.msg for e in core.step(1.0) if e.stream == "obstacles"]
    assert scans, "a scan at t = 1.0"
    seen = {d.id: d for d in scans[0].detections}  # type: ignore[attr-defined]
    assert ids["auv2"] in seen and abs(seen[ids["auv2"]].x - 14.0) < 2.0
    navs = [e.msg for e in core.step(1.0) if e.stream == "nav"]
    assert all(abs(n.x - 10.0) < 5.0 for n in navs)  # type: ignore[attr-defined]


# -- intents ---------------------------------------------------------------------------------


def _straight_path(stamp: float, x0: float, x1: float, y: float = 10.0) -> PathMsg:
    """An OK path along y from x0 to x1 (degree-1 NURBS) at 1.5 m/s."""
    return PathMsg(
        source="auv2.planner",
        seq=1,
        stamp=stamp,
        path_id=1,
        status="OK",
        reason="",
        degree=1,
        control_points=(x0, y, (x0 + x1) / 2, y, x1, y),
        weights=(1.0, 1.0, 1.0),
        knots=(0.0, 0.0, 0.5, 1.0, 1.0),
        waypoints=(x0, y, x1, y),
        length=abs(x1 - x0),
        f_l=1.0,
        max_curvature=0.0,
        v_ref=1.5,
    )


def _estimate(stamp: float, x: float, y: float = 10.0, v: float = 1.5) -> StateEstimate:
    return StateEstimate(
        source="auv2.estimator",
        seq=1,
        stamp=stamp,
        x=x,
        y=y,
        theta=0.0,
        v=v,
        w=0.0,
        covariance=(0.0,) * 25,
    )


def test_an_intent_is_the_other_vehicle_moving_along_its_path_until_it_goes_stale() -> None:
    intents = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0)
    assert intents.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    assert intents.offer("auv2", _estimate(1.0, 6.0))
    assert not intents.offer("auv1", _estimate(1.0, 6.0))  # not another vehicle's
    (o,), covered = intents.obstacles(2.0)
    assert covered == {100} and o.radius == 0.5
    assert o.x == pytest.approx(7.5, abs=0.2)  # 1 s after the estimate, at 1.5 m/s
    assert o.vx == pytest.approx(1.5, abs=1e-6)
    ahead = o.centre_at(np.array([2.0, 100.0]))  # at 1.5 m/s, then parked at the path's end
    assert ahead.ravel().tolist() == pytest.approx([10.5, 10.0, 30.0, 10.0], abs=0.2)
    assert o.advanced(2.0).x == pytest.approx(10.5, abs=0.2)
    # an older estimate arriving late changes nothing; a stale one drops the intent
    intents.offer("auv2", _estimate(0.5, 1.0))
    assert intents.obstacles(2.0)[0][0].x == pytest.approx(7.5, abs=0.2)
    assert intents.obstacles(2.9)[1] == {100}
    assert intents.obstacles(3.2) == ((), frozenset())  # 2.2 s old: its track takes over


@pytest.mark.parametrize("lane_y", [10.0, 14.0, 17.0, 20.5, 40.0])
def test_the_replan_check_bounds_far_routes_by_their_box_and_decides_as_exact_gaps_do(
    lane_y: float,
) -> None:
    # a path along y = 20; another vehicle on a lane at lane_y, crossing x 0 -> 90. Gaps are
    # only compared with rho0 and the corridor: a route whose box is farther than both from
    # the path ahead has its gaps stood in for by that bound, which must never exceed them
    cfg = PlannerConfig(corridor_halfwidth_m=3.0)
    start, goal = Pose2D(x=5.0, y=20.0, theta=0.0), Pose2D(x=95.0, y=20.0, theta=0.0)
    plan = plan_path(PlanRequest(start=start, goal=goal, v_ref_mps=1.5, vehicle_radius_m=0.5), cfg)
    policy = ReplanPolicy(cfg, vehicle_radius_m=0.5, v_ref_mps=1.5)
    policy.on_planned(0.0, plan, goal, Obstacles())
    intents = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0)
    intents.offer("auv2", _straight_path(0.0, 0.0, 90.0, y=lane_y))
    intents.offer("auv2", _estimate(0.0, 0.0, y=lane_y))
    (o,), _ = intents.obstacles(0.0)
    (bound,) = policy._sample_gaps(Obstacles(moving=(o,)), 0, 0.0)
    assert policy.pts is not None
    exact = np.hypot(*(policy.pts - o.centre_at(policy.s / 1.5)).T) - o.radius - 0.5
    far = max(cfg.rho0_m, cfg.corridor_halfwidth_m)
    if abs(lane_y - 20.0) - 1.0 >= far:  # the boxes' distance less both radii
        # at least rho0 and the corridor, so compared with them as the exact gaps would be
        assert np.all(bound >= far) and np.all(bound <= exact + 1e-9)
        assert np.ptp(bound) == 0.0  # the bound, not the samples
    else:
        assert bound == pytest.approx(exact)


def test_each_step_counts_every_other_vehicle_by_intent_or_by_track() -> None:
    intents = FleetIntents({"auv2": (100, 0.5), "auv3": (101, 0.5)}, max_age_s=2.0)
    intents.tally(0.5)  # nothing heard yet: both by track
    intents.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    intents.offer("auv2", _estimate(1.0, 6.0))
    intents.offer("auv3", _estimate(1.0, 6.0, y=20.0))  # a pose without a path: no intent
    for t in (1.5, 2.5, 3.0, 3.5):  # auv2's estimate goes stale after 3.0
        intents.tally(t)
    assert intents.counters == {
        "intent.auv2": 3,
        "intent.auv3": 0,
        "track.auv2": 2,
        "track.auv3": 5,
    }


def test_a_vehicle_at_rest_on_a_new_path_is_about_to_leave_not_parked() -> None:
    # at rest at its start, with a path: its speed rises at its ramp (0.5 m/s^2) to the
    # path's v_ref (1.5 m/s, reached after 3 s and 2.25 m), then holds
    intents = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0, ramps={"auv2": 0.5})
    intents.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    intents.offer("auv2", _estimate(0.0, 0.0, v=0.0))
    (o,), _ = intents.obstacles(0.0)
    ahead = o.centre_at(np.array([0.0, 2.0, 3.0, 5.0, 100.0]))[:, 0]
    assert ahead.tolist() == pytest.approx([0.0, 1.0, 2.25, 5.25, 30.0], abs=0.05)
    later = o.advanced(2.0)
    assert (later.x, later.speed) == pytest.approx((1.0, 1.0), abs=0.05)
    assert later.centre_at(np.array([1.0]))[0, 0] == pytest.approx(2.25, abs=0.05)
    # the same vehicle after a NO_PATH: braking on its last path, it stays put at rest
    no_path = _straight_path(0.5, 0.0, 30.0)
    intents.offer("auv2", PathMsg(**{**_fields(no_path), "status": "NO_PATH"}))
    (held,), _ = intents.obstacles(0.0)
    assert held.centre_at(np.array([10.0]))[0, 0] == pytest.approx(0.0, abs=0.05)
    # without a ramp (none known) the speed it has is taken as it is
    flat = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0)
    flat.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    flat.offer("auv2", _estimate(0.0, 0.0, v=0.0))
    assert flat.obstacles(0.0)[0][0].centre_at(np.array([10.0]))[0, 0] == pytest.approx(0.0)


def test_a_vehicle_parked_at_its_goal_is_an_obstacle_even_to_those_ahead_in_priority() -> None:
    # auv1 is first in priority: it plans around no one's intent while they are fresh. A
    # vehicle at its route's end will not move again to give way: it is an obstacle to all,
    # where its estimate is (here 1.4 m past its route's end: it overshot its goal), at rest
    first = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0, gives_way_to=frozenset())
    first.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    first.offer("auv2", _estimate(1.0, 15.0))  # under way: auv2 gives way, auv1 ignores it
    assert first.obstacles(1.5) == ((), frozenset({100}))
    for stamp, x in ((20.0, 29.2), (30.0, 31.4)):  # within 1 m of its end (the goal
        first.offer("auv2", _estimate(stamp, x, v=0.0))  # tolerance), or past it
        (parked,), covered = first.obstacles(stamp + 0.5)
        assert covered == {100} and (parked.x, parked.y) == (x, 10.0)
        assert parked.centre_at(np.array([0.0, 60.0])).ravel().tolist() == [x, 10.0, x, 10.0]


def test_another_vehicle_is_planned_around_wider_by_the_intent_margin() -> None:
    # its route (under way) and its hull parked at the route's end are both widened: where
    # it is comes from its estimate, and how near its route from its tracking
    intents = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0, margin_m=0.15)
    intents.offer("auv2", _straight_path(0.0, 0.0, 30.0))
    intents.offer("auv2", _estimate(1.0, 6.0))
    (under_way,), _ = intents.obstacles(1.5)
    intents.offer("auv2", _estimate(30.0, 29.5, v=0.0))
    (parked,), _ = intents.obstacles(30.5)
    assert isinstance(under_way, IntentObstacle) and not isinstance(parked, IntentObstacle)
    assert under_way.radius == parked.radius == pytest.approx(0.65)


def test_without_a_path_there_is_no_intent() -> None:
    intents = FleetIntents({"auv2": (100, 0.5)}, max_age_s=2.0)
    intents.offer("auv2", _estimate(1.0, 6.0))
    no_path = _straight_path(0.5, 0.0, 30.0)
    intents.offer("auv2", PathMsg(**{**_fields(no_path), "status": "NO_PATH"}))
    assert intents.obstacles(1.5) == ((), frozenset())


def _fields(m: PathMsg) -> dict[str, Any]:
    return {f: getattr(m, f) for f in m.__struct_fields__}


# -- missions --------------------------------------------------------------------------------


@pytest.mark.deterministic
@pytest.mark.slow
def test_two_vehicles_head_on_both_reach_their_goals_rho0_apart() -> None:
    s, _ = load_scenario(HEADON, ['runtime.kind="inproc"'], check=check_scenario)
    m = run_inproc(s).metrics
    assert m.reached_goal and m.vehicles_reached == 2
    assert m.vehicle_collisions == 0
    assert m.min_separation_m >= s.planner.rho0_m  # hull to hull: r1 + r2 + rho0 centres
    assert m.outcome == "success"
    assert set(m.vehicles) == {"auv1", "auv2"}
    assert all(v.outcome == "success" for v in m.vehicles.values())
    # the intent links have the default 5 % loss: re-sent, the intents are in use all along
    # but for the first plan's wait for them
    assert m.intent_fraction > 0.95
    assert m.vehicles["auv1"].intent_fraction_by_vehicle == {
        "auv2": m.vehicles["auv1"].intent_fraction
    }


@pytest.mark.heavy
@pytest.mark.deterministic
def test_a_vehicle_first_in_priority_goes_around_one_parked_at_its_goal(tmp_path: Path) -> None:
    # auv2 arrives first and parks on auv1's straight line; auv1, ahead in priority, plans
    # around no one's fresh intent, but a vehicle at its goal will not give way to it (before
    # that rule auv1 drove through auv2: hulls 1.41 m into each other)
    parked = tmp_path / "parked.toml"
    parked.write_text(
        f"""extends = "{HEADON}"
[run]
max_time_s = 90.0
[[vehicles]]
id = "auv1"
start = {{ x_m = 10.0, y_m = 20.0, theta_rad = 0.0 }}
goal = {{ x_m = 90.0, y_m = 20.0 }}
[[vehicles]]
id = "auv2"
start = {{ x_m = 50.0, y_m = 36.0, theta_rad = -1.5708 }}
goal = {{ x_m = 50.0, y_m = 20.0 }}
"""
    )
    s, _ = load_scenario(parked, ['runtime.kind="inproc"'], check=check_scenario)
    assert s.planner.deconfliction == "priority"
    m = run_inproc(s).metrics
    assert m.vehicles_reached == 2 and m.vehicle_collisions == 0, m
    assert m.vehicles["auv2"].travel_time_s < 0.5 * m.vehicles["auv1"].travel_time_s
    assert m.min_separation_m >= s.planner.rho0_m and m.outcome == "success"


@pytest.mark.deterministic
@pytest.mark.slow
def test_fleet4_in_lockstep_equals_inproc(tmp_path: Path) -> None:
    # 16 service processes and the clock over one Zenoh session each, over the first 14 s:
    # the four vehicles' first encounters (their replans at 11-13 s); whole fleet4 missions,
    # every goal reached without contact, are `scripts/bench fleet_launches` (realtime)
    s, raw = load_scenario(FLEET4, ["run.seed=3", "run.max_time_s=14.0"], check=check_scenario)
    ref = run_inproc(s)
    got = run_lockstep(s, raw, tmp_path / "logs")
    assert got.metrics.trajectory_sha256 == ref.metrics.trajectory_sha256
    assert got.metrics == ref.metrics
    for vid in ("auv1", "auv4"):
        for stream in ("path", "intent", "stats"):
            key = (f"{vid}.planner", stream)
            assert got.record.stream(*key) == ref.record.stream(*key), key


# -- launching -------------------------------------------------------------------------------


def test_service_vehicle_names_one_vehicles_service_and_refuses_what_is_not_there() -> None:
    from common.config.errors import ConfigValueError
    from services.cli.launch_commands import service_name

    fleet, _ = load_scenario(HEADON)
    single, _ = load_scenario(REPO / "configs" / "default.toml")
    assert service_name("planner", "auv2", fleet) == "auv2.planner"
    assert service_name("auv1.vehicle", None, fleet) == "auv1.vehicle"
    assert service_name("planner", None, single) == "planner"
    for name, vehicle, s, words in (
        ("planner", "auv9", fleet, "its vehicles are auv1, auv2"),
        ("planner", "auv1", single, "it has no [[vehicles]]"),
        ("planner", None, fleet, "auv1.estimator, auv1.planner"),
        ("pilot", "auv1", fleet, "no service 'auv1.pilot'"),
    ):
        with pytest.raises(ConfigValueError, match=re.escape(words)):
            service_name(name, vehicle, s)
    # as a user meets it: exit 2 at once, not after waiting for a router that is not there
    r = tidelink_cli(
        "service", "planner", str(HEADON), "--vehicle", "auv9", "--connect", "tcp/127.0.0.1:9"
    )
    assert r.returncode == 2 and "its vehicles are auv1, auv2" in r.stderr, r.stderr


def test_only_selects_a_vehicles_services_by_pattern() -> None:
    names = load_mission(_fleet(_raw())).dataflow.names
    auv2 = ("auv2.estimator", "auv2.planner", "auv2.sensor", "auv2.vehicle")
    assert select_services(names, ("auv2/*",)) == auv2
    assert select_services(names, ("auv2.*",)) == auv2
    assert select_services(names, ("auv1/planner", "*.vehicle"))[:2] == (
        "auv1.planner",
        "auv1.vehicle",
    )
    assert select_services(names, ()) == ()
    with pytest.raises(ValueError, match="'auv9/\\*' names no service"):
        select_services(names, ("auv9/*",))


def test_launch_progress_shows_every_vehicle() -> None:
    s = _fleet(_raw())
    view = MissionView(s)
    assert set(view.vehicles) == {f"auv{k}.vehicle" for k in (1, 2, 3, 4)}
    view.see("auv2.vehicle", "truth", _truth("auv2.vehicle", 92.0, 32.0).msg)
    view.see("auv2.vehicle", "truth", _truth("auv2.vehicle", 50.0, 20.0).msg)
    line = view.summary(1.0)
    assert "auv2 44 m" in line and "auv1 ?" in line
    assert 0.0 < view.fraction() < 0.25  # one of four vehicles half-way


@pytest.mark.slow
@pytest.mark.exclusive
def test_a_sigkilled_planner_leaves_its_vehicle_holding_and_the_fleet_going_on(
    tmp_path: Path,
) -> None:
    # (x3: at x6 a loaded 2-core machine let auv2 lose its pace: short of its goal once,
    # within rho0 of the held auv1 once)
    # a real launch of the head-on pair 50 m apart (8 service processes); auv1's planner is
    # SIGKILLed at t = 10 s, before they meet, and not restarted: auv1's vehicle holds, then
    # fails safe, on its own watchdog; auv2 passes it (its last intent, then its sonar track)
    # and reaches its goal; the run goes on to max_time, says what was lost, writes its
    # metrics and is no success (exit 3)
    from common.runtime.distributed.bringup import run_keys
    from services.chaos.case import CaseSetup, run_case
    from services.chaos.faults import Fault

    setup = CaseSetup(
        scenario=HEADON_SHORT, sets=("run.max_time_s=60.0",), time_scale=3.0, fault_at_s=10.0
    )
    s, _ = load_scenario(HEADON_SHORT, list(setup.sets))
    got = run_case(
        setup,
        Fault("kill", "auv1.planner"),
        tmp_path / "run",
        run_keys(s),
        load_mission(s).dataflow,
    )
    m = got.metrics
    assert m is not None
    assert got.exit_code == 3 and got.leftovers == [], (got.exit_code, got.note, got.leftovers)
    assert m.facts.end_reason == "max_time" and m.facts.failure.startswith("auv1.planner lost: ")
    assert isinstance(m.mission, FleetMetrics)
    one, two = m.mission.vehicles["auv1"], m.mission.vehicles["auv2"]
    # the kill lands at the first progress line past t = 10 s: one every 0.25 s of wall time
    # (services/chaos/case.py), before they meet even under load (one every 2 s put it at up
    # to t = 22 s, in the middle of the pass); the vehicle then flies out its 10 s command
    # sequence, holds, and fails safe to the end
    assert not one.reached_goal and one.hold_time_s + one.failsafe_time_s > 20.0
    seen = (two.outcome, two.final_distance_to_goal_m, two.min_clearance_m, two.no_path_events)
    assert two.reached_goal and two.collisions == 0 and two.hold_time_s == 0.0, seen
    assert m.mission.vehicle_collisions == 0 and m.mission.min_separation_m >= s.planner.rho0_m
    assert two.intent_fraction < 0.5  # by auv1's track after its intent went stale
