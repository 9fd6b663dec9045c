"""The run's outcome and its safety and turning metrics, on synthetic truth records: a
straight pass by one circle at a chosen distance (so the time inside rho0 and in contact is
known in closed form), and yaw-rate profiles against eq. (11)'s turning bound."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import msgspec
import numpy as np
import pytest
from helpers.records import auv, facts, ran
from helpers.testloop import LoopMetrics

from common.config.scenario import Scenario, load_scenario
from common.messages import LinkStats, ObstacleTracks, PathMsg, Track, TruthState
from common.runtime.model.record import Record
from common.world import World
from services.mission.metrics import TRACK_AHEAD_S, YAW_RATE_TOL_RPS, mission_metrics
from services.mission.outcome import OUTCOMES, classify, describe
from services.mission.records import AuvMetrics
from services.mission.verdict import mission_failure
from services.planner.reasons import PLANS_DECLINED

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
SPEED = 1.5  # m/s along y = 20
DT = 0.05  # the vehicle's truth period


def _scenario(circle_y_m: float) -> Scenario:
    """The default area with one circle of radius 2 m at (50, circle_y_m), nothing else."""
    s, _ = load_scenario(
        DEFAULT,
        [
            f"world.circles=[{{id=1, x_m=50.0, y_m={circle_y_m}, radius_m=2.0}}]",
            "world.polygons=[]",
            "world.moving=[]",
        ],
    )
    return s


def _samples(x_end: float = 95.0) -> int:
    """How many truth states a pass from x = 5 to x_end takes at SPEED."""
    return int(round((x_end - 5.0) / (SPEED * DT))) + 1


def _record(x_end: float, v: np.ndarray | None, w: np.ndarray | None) -> Record:
    """Truth along y = 20 from x = 5 at SPEED, every DT, up to x_end (95: the goal), with
    the speeds v given and the headings turning at the yaw rates w over each period (the
    positions stay on the line: the metrics of turning read the headings and speeds)."""
    n = _samples(x_end)
    t = DT * np.arange(n)
    v = np.full(n, SPEED) if v is None else v
    w = np.zeros(n) if w is None else w
    theta = np.concatenate([[0.0], np.cumsum(w[:-1] * DT)])
    rec = Record()
    for i in range(n):
        rec.add(
            "vehicle",
            "truth",
            TruthState(
                stamp=float(t[i]), source="vehicle", seq=i + 1,
                x=5.0 + SPEED * float(t[i]), y=20.0, theta=float(theta[i]), v=float(v[i]),
                w=float(w[i]),
            ),
        )  # fmt: skip
    return rec


def _metrics(
    circle_y_m: float,
    x_end: float = 95.0,
    v: np.ndarray | None = None,
    w: np.ndarray | None = None,
) -> AuvMetrics:
    s = _scenario(circle_y_m)
    return mission_metrics(_record(x_end, v, w), s, World(s.world))


def _crossing_s(hull_to_surface_m: float, offset_m: float) -> float:
    """How long a pass at offset_m from the centre of the 2 m circle stays with a clearance
    below hull_to_surface_m (hull radius 0.8 m)."""
    reach = 2.0 + 0.8 + hull_to_surface_m
    return 2.0 * math.sqrt(reach**2 - offset_m**2) / SPEED


def test_a_pass_outside_rho0_is_a_success() -> None:
    m = _metrics(24.0)  # clearance 4 - 2 - 0.8 = 1.2 m > rho0 = 1.0 m
    assert m.outcome == "success" and m.success is True
    assert m.min_clearance_m == pytest.approx(1.2)
    assert m.rho0_m == 1.0
    assert m.rho0_breach_m == 0.0 and m.time_below_rho0_s == 0.0
    assert m.time_in_contact_s == 0.0 and m.collisions == 0
    assert mission_failure(ran(m, end_reason="goal")) is None


def test_a_pass_inside_rho0_reaches_the_goal_but_is_no_success() -> None:
    m = _metrics(23.5)  # clearance 0.7 m: 0.3 m inside rho0
    assert m.reached_goal is True and m.collisions == 0
    assert m.outcome == "rho0_breach" and m.success is False
    assert m.rho0_breach_m == pytest.approx(0.3)
    # each 0.05 s state counts until the next: the sampled time is the exact one +- a period
    assert m.time_below_rho0_s == pytest.approx(_crossing_s(1.0, 3.5), abs=DT)
    assert m.time_in_contact_s == 0.0
    said = mission_failure(ran(m, end_reason="goal"))
    assert said == (
        "mission failed: goal reached, but 0.30 m inside the safety distance rho0 = 1.0 m "
        f"for {m.time_below_rho0_s:.1f} s (min clearance 0.70 m)"
    )


def test_contact_is_a_collision_whatever_else_happened() -> None:
    m = _metrics(22.5)  # clearance -0.3 m
    assert m.outcome == "collision" and m.success is False and m.collisions == 1
    assert m.time_in_contact_s == pytest.approx(_crossing_s(0.0, 2.5), abs=DT)
    assert m.time_below_rho0_s == pytest.approx(_crossing_s(1.0, 2.5), abs=DT)
    assert m.rho0_breach_m == pytest.approx(1.3)  # deeper than rho0: into the obstacle
    said = mission_failure(ran(m, end_reason="goal"))
    assert said is not None and said.startswith(
        f"mission failed: contact at t={m.first_contact_t_s:.2f} s (min clearance -0.3 m), "
        f"in contact for {m.time_in_contact_s:.2f} s; goal reached"
    )


def test_a_run_short_of_the_goal_is_not_reached_even_inside_rho0() -> None:
    m = _metrics(23.5, x_end=60.0)
    assert m.reached_goal is False and m.outcome == "not_reached"
    assert m.rho0_breach_m == pytest.approx(0.3)  # still measured and said
    said = mission_failure(ran(m, end_reason="max_time", t_end_s=36.6))
    assert said is not None and said.startswith(
        "mission failed: goal not reached (max_time at t=36.60 s, 35.0 m from the goal); "
        "0.30 m inside the safety distance rho0 = 1.0 m"
    )


def test_outcome_precedence_collision_then_not_reached_then_rho0_breach() -> None:
    table = {
        (reached, contact, below): classify(reached_goal=reached, contact=contact, below_rho0=below)
        for reached in (False, True)
        for contact in (False, True)
        for below in (False, True)
    }
    assert {k for k, v in table.items() if v == "collision"} == {
        (r, True, b) for r in (False, True) for b in (False, True)
    }
    assert table[(False, False, False)] == table[(False, False, True)] == "not_reached"
    assert table[(True, False, True)] == "rho0_breach"
    assert table[(True, False, False)] == "success"
    assert set(table.values()) == set(OUTCOMES)


def test_a_mission_that_does_not_judge_runs_gets_no_verdict() -> None:
    # (the runtime's test loop; an older metrics file is refused: tests/test_run_records.py)
    loop = LoopMetrics(final_x=1.0, final_error=None, trajectory_sha256="")
    assert mission_failure(ran(loop, end_reason="max_time")) is None


def test_time_above_the_turning_bound_and_curvature_after_the_start() -> None:
    i = np.arange(_samples())  # state i is at t = 0.05 i
    # from rest at 0.3 m/s^2 to cruise, turning at 0.3 rad/s throughout the first 2 s (R
    # = v / w far below R_min = 5 m while slow); then 0.4 rad/s (R = 3.75 m) for 3 s from
    # t = 20 s, and the bound plus half the tolerance (within it) for 10 s from t = 30 s
    v = np.minimum(0.3 * DT * i, SPEED)
    w = np.zeros(len(i))
    w[i < 40] = 0.3
    w[(i >= 400) & (i < 460)] = 0.4
    w[(i >= 600) & (i < 800)] = SPEED / 5.0 + YAW_RATE_TOL_RPS / 2.0
    m = _metrics(24.0, v=v, w=w)
    # the start: |w| > |v| / 5 + tol while v < 5 (0.3 - tol) = 1.475 m/s, i.e. all of t < 2 s
    assert m.time_above_curvature_limit_s == pytest.approx(2.0 + 3.0, abs=1e-9)
    # v > 0.3 m/s from t = 1.05 s: curvature 0.3 / 0.315 there; 1 s later it is 0.4 / 1.5
    assert m.max_executed_curvature == pytest.approx(0.3 / 0.315)
    assert m.max_executed_curvature_after_start == pytest.approx(0.4 / SPEED)


def test_a_turn_on_the_spot_is_above_the_bound_and_rest_is_not() -> None:
    i = np.arange(_samples())
    v = np.where(i < 80, 0.0, SPEED)
    w = np.where(i < 20, 0.2, 0.0)  # turning on the spot for 1 s, then 3 s at rest
    m = _metrics(24.0, v=v, w=w)
    assert m.time_above_curvature_limit_s == pytest.approx(1.0, abs=1e-9)


def test_the_words_survive_null_metrics() -> None:
    # a field without obstacles writes min_clearance_m as null (infinite): the summary line
    # of a launch must still be printed (it once raised and turned a success into exit 1)
    m = auv("success", reached_goal=True, min_clearance_m=None)
    assert describe(m, facts()).startswith("goal reached in 0.00 s")
    m = auv("rho0_breach", reached_goal=True, rho0_m=1.0)
    assert "inside the safety distance rho0 = 1.0 m" in describe(m, facts())


def _tracked(offset_m: float, dv_mps: float, until_s: float = 60.0) -> AuvMetrics:
    """The pass of `_record` with one moving obstacle (id 7: a line at 0.5 m/s east along
    y = 35) and an estimator tracking it every 0.5 s up to until_s, offset_m off in x and
    dv_mps off in vx; and one static circle, tracked too, which the tracking metrics leave
    out."""
    s, _ = load_scenario(
        DEFAULT,
        [
            "world.circles=[{id=1, x_m=50.0, y_m=5.0, radius_m=2.0}]",
            "world.polygons=[]",
            "world.moving=[{id=7, kind='line', x0_m=10.0, y0_m=35.0, vx_mps=0.5, vy_mps=0.0}]",
        ],
    )
    rec = _record(95.0, None, None)
    for i in range(round(until_s / 0.5) + 1):  # the pass spans 0-60 s
        t = 0.5 * i
        cov = tuple(np.eye(6).ravel())
        moving = Track(id=7, x=10.0 + 0.5 * t + offset_m, y=35.0, vx=0.5 + dv_mps, vy=0.0,
                       ax=0.0, ay=0.0, radius=1.0, covariance=cov)  # fmt: skip
        static = Track(id=1, x=53.0, y=5.0, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=2.0,
                       covariance=cov)  # fmt: skip
        rec.add("estimator", "tracks", ObstacleTracks(stamp=t, source="estimator", seq=i + 1,
                                                      tracks=(moving, static)))  # fmt: skip
    return mission_metrics(rec, s, World(s.world))


def test_tracking_metrics_set_moving_tracks_and_their_extrapolation_against_truth() -> None:
    exact = _tracked(0.0, 0.0)
    assert exact.tracking_rms_m == exact.tracking_max_m == 0.0  # the 3 m static is out
    assert exact.tracking_ahead_max_m == pytest.approx(0.0, abs=1e-12)
    off = _tracked(0.3, 0.1)  # 0.3 m off now; 0.3 + 0.1 TRACK_AHEAD_S m off when extrapolated
    assert off.tracking_rms_m == pytest.approx(0.3) and off.tracking_max_m == pytest.approx(0.3)
    assert off.tracking_ahead_rms_m == pytest.approx(0.3 + 0.1 * TRACK_AHEAD_S)


def test_tracking_metrics_are_named_and_null_when_nothing_was_measured() -> None:
    # a run's key set does not depend on how far it got: no track yet, or none 2 s old
    early = msgspec.to_builtins(_tracked(0.0, 0.0, until_s=-1.0))  # as metrics.json has it
    assert {k: v for k, v in early.items() if "tracking" in k} == {
        "tracking_rms_m": None,
        "tracking_max_m": None,
        "tracking_ahead_rms_m": None,
        "tracking_ahead_max_m": None,
    }


def test_a_run_without_moving_obstacles_has_no_tracking_metrics() -> None:
    m = _metrics(20.0)  # one static circle, no moving obstacle
    assert not any(k.startswith("tracking") for k in msgspec.to_builtins(m))  # absent keys


def test_plans_declined_come_from_the_planners_last_statistics() -> None:
    # a declined plan publishes no path (services/planner/adoption.py): the planner counts them
    s = _scenario(24.0)
    rec = _record(95.0, None, None)
    assert mission_metrics(rec, s, World(s.world)).plans_declined == 0  # no statistics
    for seq, n in ((1, 1), (2, 3)):
        stats = LinkStats(
            stamp=float(seq), source="planner", seq=seq, links=(), counters={PLANS_DECLINED: n}
        )
        rec.add("planner", "stats", stats)
    assert mission_metrics(rec, s, World(s.world)).plans_declined == 3


def test_plans_declined_by_reason_come_from_the_planners_counters_by_code() -> None:
    # decline.py names the rule that declined a plan; the planner counts each code apart
    s = _scenario(24.0)
    rec = _record(95.0, None, None)
    assert mission_metrics(rec, s, World(s.world)).plans_declined_by_reason == {}
    counters = {PLANS_DECLINED: 3, f"{PLANS_DECLINED}.overtaken": 1}
    counters[f"{PLANS_DECLINED}.kept_path_in_force"] = 2
    stats = LinkStats(stamp=1.0, source="planner", seq=1, links=(), counters=counters)
    rec.add("planner", "stats", stats)
    m = mission_metrics(rec, s, World(s.world))
    assert m.plans_declined == 3
    assert m.plans_declined_by_reason == {"kept_path_in_force": 2, "overtaken": 1}


def _path(seq: int, strategy: str, rejected: tuple[str, ...] = ()) -> PathMsg:
    """A NO_PATH (no curve to measure against) asked for no_path, with reason codes."""
    return PathMsg(
        stamp=float(seq), source="planner", seq=seq, path_id=seq, status="NO_PATH",
        reason="no_path: walled off", degree=0, control_points=(), weights=(), knots=(),
        waypoints=(), length=0.0, f_l=0.0, max_curvature=0.0, v_ref=0.0,
        strategy=strategy, rejected=rejected,
    )  # fmt: skip


def test_plan_strategies_count_the_paths_codes_into_metrics_json() -> None:
    # each path message names the strategy that made it and those rejected on the way
    # (services/planner/reasons.py): metrics.json counts both by code
    s = _scenario(24.0)
    rec = _record(95.0, None, None)
    plain = msgspec.to_builtins(mission_metrics(rec, s, World(s.world)))
    assert "plan_strategies" not in plain  # no path: nothing to count
    rec.add("planner", "path", _path(1, "no_route", ("searched",)))
    rec.add("planner", "path", _path(2, "no_curve", ("searched", "turned_first")))
    rec.add("planner", "path", _path(3, "no_route", ("searched_static",)))
    written = json.loads(json.dumps(ran(mission_metrics(rec, s, World(s.world))).to_json()))
    assert written["plan_strategies"] == {"no_curve": 1, "no_route": 2}
    assert written["plan_strategies_rejected"] == {
        "searched": 2,
        "searched_static": 1,
        "turned_first": 1,
    }
    # a recording of paths from before the codes counts none (absent, not empty)
    old = _record(95.0, None, None)
    old.add("planner", "path", _path(1, ""))
    assert "plan_strategies" not in msgspec.to_builtins(mission_metrics(old, s, World(s.world)))


def test_the_metrics_load_neither_the_planners_search_nor_a_kd_tree() -> None:
    # a launcher computes a run's metrics: it read a path's curve, and loaded the whole planner
    # (scipy's graph and image modules) and scipy.spatial with it, ~0.45 s of every launch
    probe = (
        "import sys, services.mission.metrics; "
        "print(sorted(m for m in ('scipy.spatial', 'scipy.ndimage', 'services.planner.plan') "
        "if m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, check=True, timeout=60
    ).stdout
    assert out.strip() == "[]"
