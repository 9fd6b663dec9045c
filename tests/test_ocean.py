"""The real ocean (issue 60): AUV navigation, the estimator's current, heading bias and gate,
the loop's compensation of the current, station keeping, and a vehicle carried out of the
area that comes back."""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

import msgspec
import numpy as np
import pytest
from helpers.planner_world import planner_core

from common.config.controller import ControllerConfig
from common.config.estimator import EstimatorConfig
from common.config.planner import PlannerConfig
from common.config.scenario import load_scenario
from common.config.sensor import SensorConfig
from common.config.vehicle import VehicleConfig
from common.config.world import AreaConfig, CircleObstacleConfig, WorldConfig
from common.messages import NavFix, Odometry, PositionFix, StateEstimate, TruthState
from common.runtime.model.core import Delivery
from common.runtime.model.inproc import run_inproc
from common.world import World
from common.world.check import check_scenario
from services.control.command.link import (
    GIVE_WAY_FRACTION,
    CommandLink,
    Prediction,
    believed_current,
    doubted_current,
    position_std,
)
from services.control.controllers.base import Limits
from services.control.controllers.nurbs_tracker import NurbsTracker
from services.estimator import EstimatorCore
from services.planner.geometry.clearance import StaticField, current_pushes_clear
from services.sensor.core import SensorCore
from services.sensor.models import nav_fix, odometry

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "configs" / "default.toml"
OCEAN = ROOT / "configs" / "ocean.toml"

Truth = Callable[[float], TruthState]


def _straight(c: tuple[float, float], v: float = 1.5, heading: float = 0.0) -> Truth:
    """A vehicle at speed v through the water on a constant heading from (5, 20), carried by
    the current c."""
    gx, gy = v * math.cos(heading) + c[0], v * math.sin(heading) + c[1]
    return lambda t: TruthState(
        stamp=t, x=5.0 + gx * t, y=20.0 + gy * t, theta=heading, v=v, w=0.0,
        current_x=c[0], current_y=c[1],
    )  # fmt: skip


def test_the_auv_sensor_sends_odometry_every_step_and_a_usbl_fix_every_few_seconds() -> None:
    cfg = SensorConfig(navigation="dvl_usbl", obstacle_rate_hz=2.0, usbl_outlier_p=0.2)
    core = SensorCore(cfg, World(WorldConfig()), np.random.default_rng(3))
    truth = _straight((0.0, 0.3))  # a cross current: the DVL sees it across the hull
    odo: list[Odometry] = []
    fixes: list[PositionFix] = []
    for k in range(1200):  # 120 s at 10 Hz (180 m: within the world's plausible span)
        t = round(0.1 * k, 9)
        core.deliver(Delivery(source="vehicle", stream="truth", msg=truth(t), t=t))
        for e in core.step(t):
            assert e.stream in ("odometry", "fix", "obstacles")  # never a 10 Hz "nav" fix
            if isinstance(e.msg, Odometry):
                odo.append(e.msg)
            elif isinstance(e.msg, PositionFix):
                fixes.append(e.msg)
    assert len(odo) == 1200
    gaps = np.diff([f.stamp for f in fixes])
    assert gaps.min() >= cfg.usbl_period_min_s - 0.1 and gaps.max() <= cfg.usbl_period_max_s + 0.1
    locked = [o for o in odo if o.bottom_lock]
    # bottom lock is lost at 0.02 / s for ~3 s: locked most of the time, not always
    assert 0.75 < len(locked) / len(odo) < 1.0 and core.dvl_dropouts >= 1
    assert np.mean([o.v_ground for o in locked]) == pytest.approx(0.3, abs=0.01)
    assert np.mean([o.u_ground for o in locked]) == pytest.approx(1.5, abs=0.01)
    assert np.mean([o.water_speed for o in odo]) == pytest.approx(1.5, abs=0.01)
    # one heading bias for the whole run, under white noise of the stated size
    heads = np.array([o.heading for o in odo])
    assert np.std(heads) == pytest.approx(cfg.ahrs_std_heading_rad, rel=0.1)
    assert abs(np.mean(heads)) < 4.0 * cfg.ahrs_bias_std_rad
    # a fifth of the USBL fixes are outliers, metres off
    off = np.array([math.hypot(f.x - truth(f.stamp).x, f.y - truth(f.stamp).y) for f in fixes])
    assert 0.1 < float(np.mean(off > 5.0 * cfg.usbl_std_m)) < 0.35


def _dvl_usbl(
    est: EstimatorCore, truth: Truth, until_s: float, fix_at: Callable[[float], tuple[float, float]]
) -> StateEstimate:
    """Odometry every 0.1 s (no bias), a USBL fix at fix_at(t) every 3 s; the last estimate."""
    cfg = SensorConfig(navigation="dvl_usbl", ahrs_bias_std_rad=0.0)
    rng = np.random.default_rng(5)
    last = None
    for k in range(round(until_s / 0.1) + 1):
        t = round(0.1 * k, 9)
        m = odometry(truth(t), cfg, 0.0, True, rng.standard_normal(5))
        est.deliver(Delivery(source="sensor", stream="odometry", msg=m, t=t))
        if k % 30 == 0:
            x, y = fix_at(t)
            fix = PositionFix(stamp=t, seq=k + 1, x=x, y=y, std_xy=0.5)
            est.deliver(Delivery(source="sensor", stream="fix", msg=fix, t=t))
        last = est.step(t)[0].msg
    assert isinstance(last, StateEstimate)
    return last


def test_dead_reckoning_with_usbl_fixes_learns_the_current_and_gates_an_outlier() -> None:
    truth = _straight((0.0, 0.3))
    est = EstimatorCore(EstimatorConfig(), (5.0, 20.0, 0.0), start_speed_mps=1.5)

    def fix_at(t: float) -> tuple[float, float]:
        q = truth(t)
        return (q.x + 15.0, q.y) if t == 30.0 else (q.x, q.y)  # one outlier, 15 m off

    out = _dvl_usbl(est, truth, 60.0, fix_at)
    q = truth(60.0)
    assert math.hypot(out.x - q.x, out.y - q.y) < 0.5
    assert (out.current_x, out.current_y) == pytest.approx((0.0, 0.3), abs=0.03)
    assert est.counters["fixes_gated_out"] == 1  # the outlier, and it moved nothing


def test_a_filter_that_is_lost_believes_two_fixes_that_agree() -> None:
    # the estimator believes the vehicle 20 m from where it is (a wrong start): the first fix
    # is gated as an outlier, the second too, but agrees with it: the filter moves to them
    truth = _straight((0.0, 0.0))
    est = EstimatorCore(EstimatorConfig(), (5.0, 0.0, 0.0), start_speed_mps=1.5)
    out = _dvl_usbl(est, truth, 7.0, lambda t: (truth(t).x, truth(t).y))
    assert math.hypot(out.x - truth(7.0).x, out.y - truth(7.0).y) < 1.0
    assert est.counters["fixes_gated_out"] == 2 and est.resets["vehicle_filter"] == 1


def test_ten_hertz_fixes_in_a_cross_current_keep_the_estimate_on_the_vehicle() -> None:
    # issue 60: a 0.2 m/s cross current drove the old filter 7 m off the vehicle (RMS 7.1 m)
    truth = _straight((0.0, 0.2))
    cfg = SensorConfig()
    est = EstimatorCore(EstimatorConfig(), (5.0, 20.0, 0.0), start_speed_mps=1.5)
    rng = np.random.default_rng(8)
    errs = []
    for k in range(600):
        t = round(0.1 * k, 9)
        fix: NavFix = nav_fix(truth(t), cfg, rng.standard_normal(4))
        est.deliver(Delivery(source="sensor", stream="nav", msg=fix, t=t))
        m = est.step(t)[0].msg
        assert isinstance(m, StateEstimate)
        errs.append(math.hypot(m.x - truth(t).x, m.y - truth(t).y))
    assert math.sqrt(np.mean(np.square(errs[100:]))) < 0.25
    assert (m.current_x, m.current_y) == pytest.approx((0.0, 0.2), abs=0.05)


def test_the_course_rate_gain_turns_the_law_into_the_yaw_rate_the_hull_needs() -> None:
    # heading east at 1.5 m/s in a following current, then a head current: the course over
    # ground turns at w v (g . e) / U^2 when the heading turns at w (module docstring)
    for c in ((0.3, 0.0), (-0.3, 0.0), (0.1, 0.25)):
        ctrl = NurbsTracker(ControllerConfig().nurbs, Limits.from_vehicle(VehicleConfig()))
        ctrl.current = c
        ctrl.water_speed = 1.5
        pose = (0.0, 0.0, 0.3, 1.5, 0.0)
        chi0 = ctrl.over_ground(pose)[2]
        w, h = 0.1, 1e-5
        chi1 = ctrl.over_ground((0.0, 0.0, 0.3 + w * h, 1.5, 0.0))[2]
        course_rate = (chi1 - chi0) / h
        assert ctrl.finish(1.5, course_rate)[1] == pytest.approx(w, rel=1e-4)


def test_a_stop_in_a_known_current_keeps_station_head_to_it() -> None:
    link = CommandLink(PlannerConfig(), ControllerConfig(), VehicleConfig())
    est = StateEstimate(
        stamp=0.0, x=50.0, y=20.0, theta=0.0, v=1.0, w=0.0, covariance=(0.01,) * 25,
        current_x=0.0, current_y=-0.4, current_std=0.01,
    )  # fmt: skip
    pred = link.predict(0.0, est)
    vs, ws = link.stop(0.0, pred)
    assert ws[0] > 0.0  # the current runs south: it turns to port, to head north
    # it comes about faster than the current flows, and once head to it makes way at its speed
    assert vs[0] > 0.5 and vs[-1] == pytest.approx(0.4, abs=0.03)
    assert all(a >= b - 1e-9 for a, b in zip(vs, vs[1:], strict=False))
    # still water, or a current it cannot yet tell from the noise of its fixes: a plain stop
    calm = StateEstimate(
        stamp=0.0, x=50.0, y=20.0, theta=0.0, v=1.0, w=0.0, covariance=(0.01,) * 25,
        current_x=0.0, current_y=-0.2, current_std=0.15,
    )  # fmt: skip
    assert link.stop(0.0, link.predict(0.0, calm)) == ([0.0] * len(vs), [0.0] * len(vs))


def test_a_current_told_from_the_noise_is_doubted_one_std_stronger_along_itself() -> None:
    def est(cx: float, cy: float, std: float) -> StateEstimate:
        return StateEstimate(
            stamp=0.0, x=0.0, y=0.0, theta=0.0, v=1.0, w=0.0, covariance=(0.01,) * 25,
            current_x=cx, current_y=cy, current_std=std,
        )  # fmt: skip

    # learning a 0.3 m/s current: 0.2 believed-ish, std 0.08; it may yet be 0.28
    learning = est(0.12, 0.16, 0.08)
    bx, by = believed_current(learning)
    dx, dy = doubted_current(learning)
    assert math.hypot(dx, dy) == pytest.approx(0.28)
    assert math.atan2(dy, dx) == pytest.approx(math.atan2(0.16, 0.12))
    assert math.hypot(bx, by) < 0.2 < math.hypot(dx, dy)
    # a wander within twice its std (still water): no stronger current is doubted
    calm = est(0.05, -0.04, 0.05)
    assert doubted_current(calm) == believed_current(calm)
    assert doubted_current(est(0.0, 0.0, 0.0)) == (0.0, 0.0)


def test_the_position_std_is_the_covariances_larger_axis() -> None:
    cov = np.zeros((5, 5))
    cov[:2, :2] = [[0.05, 0.02], [0.02, 0.01]]
    est = StateEstimate(
        stamp=0.0, x=0.0, y=0.0, theta=0.0, v=1.0, w=0.0, covariance=tuple(cov.ravel()),
    )  # fmt: skip
    assert position_std(est) == pytest.approx(math.sqrt(np.linalg.eigvalsh(cov[:2, :2])[-1]))


def test_a_stop_facing_downstream_comes_about_before_the_current_carries_it_far() -> None:
    # issue 60, ocean + faults with the planner topside, seed 800 (fuzzy PID): in NO_PATH,
    # facing downstream, it made way at the current's speed, turning at v / R_min: a minute to
    # come about, twice the current's drift all the while, into an obstacle 20 m on. Coming
    # about on R_min takes it R_min downstream in the water, plus the current's drift while
    # it turns (pi R_min / v at v): at cruise speed ~9 m here, at the current's speed ~21 m
    vehicle = VehicleConfig()
    link = CommandLink(PlannerConfig(), ControllerConfig(), vehicle)
    c, r = 0.4, vehicle.turn_radius_min_m
    pose = (50.0, 20.0, -math.pi / 2, 0.4, 0.0)
    south = 0.0
    for k in range(40):  # a stop asked every second for 40 s, from where the vehicle is
        est = StateEstimate(
            stamp=float(k), x=pose[0], y=pose[1], theta=pose[2], v=pose[3], w=pose[4],
            covariance=(0.01,) * 25, current_x=0.0, current_y=-c, current_std=0.01,
        )  # fmt: skip
        pred = link.predict(float(k), est)
        vs, ws = link.stop(float(k), pred)
        for v, w in zip(vs[:10], ws[:10], strict=True):
            pose = link.model.advance(pose, v, w, link.step_s)
            south = max(south, 20.0 - pose[1])
    assert south < r + c * math.pi * r / vehicle.cruise_speed_mps + 1.0
    # ... and then holds its ground, head to the current
    assert abs(math.remainder(pose[2] - math.pi / 2, 2.0 * math.pi)) < math.radians(20.0)
    assert 20.0 - pose[1] < south


def test_a_stop_that_would_come_about_into_an_obstacle_drifts_instead() -> None:
    # issue 60, ocean seed 1505 (fuzzy PID): in NO_PATH, heading downstream 6 m short of
    # obstacle 5, station keeping came about towards the current at cruise speed on R_min and
    # swept the hull into the obstacle: 17 s in contact. Default scenario: circle 2 at (32, 8)
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    core = planner_core(s)

    def at(x: float, y: float, theta: float) -> Prediction:
        est = StateEstimate(
            stamp=0.0, x=x, y=y, theta=theta, v=1.5, w=0.0, covariance=(0.01,) * 25,
            current_x=0.25, current_y=-0.27, current_std=0.01,
        )  # fmt: skip
        return core.link.predict(0.0, est)

    # heading east 7 m short of it, the current running south-east: coming about to the
    # north-west sweeps the hull into circle 2; drifting does not go as deep
    pred = at(24.3, 6.0, 0.0)
    keep = core.link.station_keeper()
    assert keep is not None
    station = core.stopping._least_clearance(pred, keep)
    drift = core.stopping._least_clearance(pred, lambda pose: (0.0, 0.0))
    assert station < 0.0 < drift - station and core.stopping.hold(pred) == "drift"
    vs, ws = core.link.stop(0.0, pred, hold="drift")
    assert vs == [0.0] * len(vs) and ws == [0.0] * len(ws)
    # in open water, or already head to the current, station is kept
    assert core.stopping.hold(at(10.0, 30.0, 0.0)) == "station"
    assert core.stopping.hold(at(24.3, 6.0, 2.3)) == "station"


def test_a_stop_with_an_obstacle_close_upstream_lets_the_current_carry_it_clear() -> None:
    # issue 60, ocean + faults, seed 809: station kept head to the current, the hull was held
    # at an obstacle upstream of it, in contact for 153 s with no way out within R_min
    link = CommandLink(PlannerConfig(), ControllerConfig(), VehicleConfig())
    est = StateEstimate(
        stamp=0.0, x=50.0, y=20.0, theta=math.pi / 2, v=0.4, w=0.0, covariance=(0.01,) * 25,
        current_x=0.0, current_y=-0.4, current_std=0.01,
    )  # fmt: skip
    vs, _ = link.stop(0.0, link.predict(0.0, est), hold="give_way")
    assert all(v == pytest.approx(0.4 * GIVE_WAY_FRACTION, abs=0.01) for v in vs)
    # the current runs south: an obstacle north of the vehicle is upstream, one south is not
    static = StaticField.build((CircleObstacleConfig(id=1, x_m=50.0, y_m=24.0, radius_m=2.0),), ())
    south = (0.0, -0.4)
    assert current_pushes_clear(50.0, 20.0, static, (), south, keep_m=2.5)
    assert not current_pushes_clear(50.0, 28.0, static, (), south, keep_m=2.5)
    assert not current_pushes_clear(50.0, 15.0, static, (), south, keep_m=2.5)  # far from it
    assert not current_pushes_clear(50.0, 20.0, static, (), (0.0, 0.4), keep_m=2.5)


@pytest.mark.heavy
def test_a_vehicle_carried_out_of_the_area_comes_back_to_its_goal() -> None:
    # issue 60's dead end: a vehicle outside the area heading away from it had no plan back
    # (NO_PATH, 154 times). Under way at 1.5 m/s 1.5 m from the southern edge, heading
    # south-east, it is out of the area before its first plan: it comes about and goes home
    s, _ = load_scenario(
        DEFAULT,
        [
            "world.moving=[]",
            "world.start.x_m=60.0",
            "world.start.y_m=1.5",
            "world.start.theta_rad=-0.9",
            "world.start.speed_mps=1.5",
            "run.max_time_s=80",
        ],
        check=check_scenario,
    )
    r = run_inproc(s)
    truth = [q for q in r.record.stream("vehicle", "truth") if isinstance(q, TruthState)]
    area: AreaConfig = s.world.area
    outside = [q for q in truth if not area.contains(q.x, q.y)]
    assert outside, "the vehicle never left the area: the case is not what it claims"
    assert r.reason == "goal" and r.metrics.success is True
    assert r.metrics.collisions == 0
    reasons = [p.reason for p in r.record.stream("planner", "path")]  # type: ignore[attr-defined]
    assert any("come about" in why or "outside the area" in why for why in reasons), reasons


@pytest.mark.heavy
def test_the_ocean_scenario_runs_its_models_and_reports_consistency() -> None:
    s, _ = load_scenario(OCEAN, ["run.max_time_s=30"], check=check_scenario)
    assert s.vehicle.model == "fossen3dof" and s.sensor.navigation == "dvl_usbl"
    r = run_inproc(s)
    m = r.metrics
    assert r.record.stream("sensor", "odometry") and r.record.stream("sensor", "fix")
    truth = [q for q in r.record.stream("vehicle", "truth") if isinstance(q, TruthState)]
    assert max(abs(q.sway) for q in truth) > 0.01  # the hull slips in its turns
    assert min(math.hypot(q.current_x, q.current_y) for q in truth) > 0.1
    assert m.estimation_rms_m < 1.0 and m.current_error_rms_mps < 0.1
    assert 0.0 < m.nees_mean < 10.0 and 0.5 < m.nees_in_band <= 1.0
    for key in ("max_executed_curvature", "time_above_curvature_limit_s", "max_ground_curvature"):
        assert key in msgspec.to_builtins(m)  # in metrics.json
