"""Controller building blocks: references, prediction, fuzzy inference, the shared speed
profile, saturation, config."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from common.config.controller import (
    ControllerConfig,
    ControllerKind,
    FuzzyPidGains,
    NurbsGains,
    SpeedConfig,
)
from common.config.vehicle import VehicleConfig
from services.control.controllers import (
    Backstepping,
    Circle,
    ImmuneFuzzyPid,
    Limits,
    NurbsTracker,
    Polyline,
    StraightLine,
    make_controller,
    predict_pose,
)
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import crab_angle, path_errors
from services.control.controllers.follower import course_over_ground
from services.control.controllers.fuzzy import (
    DKD_TABLE,
    DKI_TABLE,
    DKP_TABLE,
    MamdaniTables,
    memberships,
    parse_table,
)
from services.control.controllers.speed import SpeedProfile, target_speed

LIMITS = Limits.from_vehicle(VehicleConfig())


def test_straight_line_reference() -> None:
    ref: ArcLengthReference = StraightLine(x0=1.0, y0=1.0, x1=4.0, y1=5.0, v_ref=1.0)
    assert ref.length == 5.0
    assert math.isclose(ref.closest_s(4.0 + 4.0, 5.0 - 3.0, None), 5.0)  # clamped at the end
    # 3 m to the left of s = 2 (point (2.2, 2.6), left normal (-0.8, 0.6)) projects to s = 2
    assert math.isclose(ref.closest_s(2.2 - 2.4, 2.6 + 1.8, None), 2.0)
    assert ref.closest_s(-5.0, 1.0, None) == 0.0  # clamped at the start
    x, y = ref.point_at_s(2.5)
    assert math.isclose(x, 2.5) and math.isclose(y, 3.0)
    assert (
        math.isclose(ref.heading_at_s(0.0), math.atan2(4.0, 3.0)) and ref.curvature_at_s(1.0) == 0.0
    )
    # a point 2 m to the left of the direction of travel has e_y = +2
    e_y, e_th = path_errors(2.5 - 2.0 * 0.8, 3.0 + 2.0 * 0.6, ref.heading_at_s(0.0), ref, 2.5)
    assert math.isclose(e_y, 2.0) and abs(e_th) < 1e-15


@pytest.mark.parametrize("ccw", [True, False])
def test_circle_reference(ccw: bool) -> None:
    ref = Circle(cx=2.0, cy=-1.0, radius=8.0, phase0=0.3, ccw=ccw, turns=3.0)
    lap = 2.0 * math.pi * 8.0
    sign = 1.0 if ccw else -1.0
    assert math.isclose(ref.curvature_at_s(1.0), sign / 8.0)
    for s in (0.5, 10.0, lap + 3.0, 2.0 * lap + 40.0):
        x, y = ref.point_at_s(s)
        assert math.isclose(math.hypot(x - 2.0, y + 1.0), 8.0)
        # the heading is the direction of d point / ds (central difference, 1e-6)
        x1, y1 = ref.point_at_s(s + 1e-6)
        x0, y0 = ref.point_at_s(s - 1e-6)
        assert (
            abs(math.remainder(math.atan2(y1 - y0, x1 - x0) - ref.heading_at_s(s), 2 * math.pi))
            < 1e-6
        )
        # a point 1.5 m outside projects back onto s when the hint is on the same lap
        ox, oy = 2.0 + (x - 2.0) * 9.5 / 8.0, -1.0 + (y + 1.0) * 9.5 / 8.0
        assert math.isclose(ref.closest_s(ox, oy, s + 2.0), s, abs_tol=1e-9)
        e_y, _ = path_errors(ox, oy, ref.heading_at_s(s), ref, s)
        assert math.isclose(e_y, -1.5 * sign)  # outside is to the right of a ccw circle


def test_polyline_reference() -> None:
    ref = Polyline(points=(0.0, 0.0, 10.0, 0.0, 10.0, 10.0, 0.0, 10.0), window_m=4.0)
    assert ref.length == 30.0
    assert math.isclose(ref.closest_s(12.0, 4.0, None), 14.0)
    assert math.isclose(ref.heading_at_s(14.0), 0.5 * math.pi)
    assert ref.point_at_s(25.0) == (5.0, 10.0)
    # (5, 4) is closest to the first leg, but with a hint on the last leg (only legs within
    # 4 m of the hint are searched) it stays there
    assert math.isclose(ref.closest_s(5.0, 4.0, None), 5.0)
    assert math.isclose(ref.closest_s(5.0, 4.0, 25.0), 25.0)
    with pytest.raises(ValueError, match="points"):
        Polyline(points=(0.0, 0.0, 1.0))


def _rk4_unicycle(pose: tuple[float, ...], h: float, n: int = 2000) -> tuple[float, ...]:
    x, y, th, v, w = pose
    dt = h / n
    for _ in range(n):  # eq. (7) with exact theta(t): integrate x, y by RK4 in time

        def f(t: float, th0: float = th) -> tuple[float, float]:
            a = th0 + w * t
            return v * math.cos(a), v * math.sin(a)

        k1, k2, k4 = f(0.0), f(0.5 * dt), f(dt)
        x += dt / 6.0 * (k1[0] + 4.0 * k2[0] + k4[0])
        y += dt / 6.0 * (k1[1] + 4.0 * k2[1] + k4[1])
        th += w * dt
    return x, y, th, v, w


@pytest.mark.parametrize("w", [0.0, 1e-12, 0.2, -0.45])
def test_predict_pose_matches_unicycle_integration(w: float) -> None:
    # the closed-form arc agrees with a numerical integration of eq. (7) to 1e-9 m
    pose = (3.0, -2.0, 0.7, 1.4, w)
    got = predict_pose(pose, 1.7)
    want = _rk4_unicycle(pose, 1.7)
    assert max(abs(a - b) for a, b in zip(got, want, strict=True)) < 1e-9
    assert predict_pose(pose, 0.0) == pose


def test_fuzzy_tables_and_memberships() -> None:
    for table in (DKP_TABLE, DKI_TABLE, DKD_TABLE):
        t = parse_table(table)
        assert t.shape == (7, 7) and t.min() >= -3 and t.max() <= 3
    # triangular terms form a partition of unity on the universe
    xs = np.linspace(-3.0, 3.0, 601)
    assert np.allclose(memberships(xs).sum(axis=-1), 1.0)
    # beyond the universe the shoulders saturate
    assert memberships(7.0)[6] == 1.0 and memberships(-9.0)[0] == 1.0


def _naive_mamdani(table: str, e: float, de: float) -> float:
    """Rule-by-rule Mamdani (min, max, centroid), the reference for the vectorised engine."""
    rules = parse_table(table)
    grid = np.linspace(-3.0, 3.0, 121)
    mu_e, mu_de = memberships(e), memberships(de)
    agg = np.zeros_like(grid)
    for i in range(7):
        for j in range(7):
            fire = min(mu_e[i], mu_de[j])
            out = np.maximum(0.0, 1.0 - np.abs(grid - rules[i, j]))
            agg = np.maximum(agg, np.minimum(fire, out))
    return float((agg * grid).sum() / agg.sum())


@settings(max_examples=60, deadline=None)
@given(st.floats(-4.0, 4.0), st.floats(-4.0, 4.0))
def test_vectorised_mamdani_matches_rule_by_rule(e: float, de: float) -> None:
    got = MamdaniTables(DKP_TABLE, DKI_TABLE, DKD_TABLE).infer(e, de)
    for k, table in enumerate((DKP_TABLE, DKI_TABLE, DKD_TABLE)):
        assert abs(got[k] - _naive_mamdani(table, e, de)) < 1e-12
        assert -3.0 <= got[k] <= 3.0


def test_fuzzy_inference_at_known_points() -> None:
    tables = MamdaniTables(DKP_TABLE, DKI_TABLE, DKD_TABLE)
    # (ZO, ZO): dKp = ZO, dKi = ZO, dKd = NS (a symmetric triangle: centroid -1)
    assert np.allclose(tables.infer(0.0, 0.0), [0.0, 0.0, -1.0], atol=1e-12)
    # (NB, NB): dKp = PB, dKi = NB, dKd = PS; PB is the half triangle [2, 3] peaking at 3:
    # centroid 8/3 (0.02 for the 0.05 output grid)
    out = tables.infer(-3.0, -3.0)
    assert abs(out[0] - 8.0 / 3.0) < 0.02 and abs(out[1] + 8.0 / 3.0) < 0.02
    assert abs(out[2] - 1.0) < 1e-12


def test_immune_gain_stays_in_its_band() -> None:
    # K = K1 (1 - eta f) with f in [0, 1): K1 (1 - eta) < K <= K1, and K = K1 when steady
    g = FuzzyPidGains()
    ctrl = ImmuneFuzzyPid(g, LIMITS)
    ref = StraightLine(x0=0.0, y0=0.0, x1=100.0, y1=0.0)
    ks = []
    for k in range(60):
        y = 2.0 * math.sin(0.7 * k)  # a pose that jumps around: large du
        ctrl.command(0.1 * k, (float(k), y, 0.0, 1.0, 0.0), ref)
        ks.append(ctrl.last_gains[3])
    assert min(ks) > g.immune_k1 * (1.0 - g.immune_eta) and max(ks) <= g.immune_k1
    assert min(ks) < 0.9 * g.immune_k1  # the suppression did act
    ctrl.reset()
    for k in range(5):
        ctrl.command(0.1 * k, (float(k), 0.0, 0.0, 1.0, 0.0), ref)  # on the line: u = 0
    assert ctrl.last_gains[3] == g.immune_k1


SPEED = SpeedConfig()


def test_the_profile_slows_for_the_tightest_curvature_ahead() -> None:
    # kappa = 1/3 on a 3 m circle: v |kappa| <= 0.7 w_max = 0.35 rad/s -> v = 1.05 m/s;
    # on an 8 m circle 1.5 m/s needs 0.19 rad/s: no reduction
    assert math.isclose(target_speed(Circle(cx=0.0, cy=0.0, radius=3.0), 0.0, SPEED, LIMITS), 1.05)
    assert target_speed(Circle(cx=0.0, cy=0.0, radius=8.0), 0.0, SPEED, LIMITS) == 1.5

    # a 3 m arc 4 m ahead on a line (a polyline has no curvature: a stand-in reference whose
    # curvature is 1/3 from s = 24 on) slows down 4 m ahead of it, not 5 m: the preview
    # window is v_cruise * preview_s = 4.5 m long
    class Bend(StraightLine):
        def curvature_at_s(self, s: float) -> float:
            return 1.0 / 3.0 if s >= 24.0 else 0.0

    bend = Bend(x0=0.0, y0=0.0, x1=100.0, y1=0.0)
    assert math.isclose(target_speed(bend, 20.0, SPEED, LIMITS), 1.05)
    assert target_speed(bend, 18.0, SPEED, LIMITS) == 1.5


def test_the_profile_stops_at_the_end_of_the_path() -> None:
    # v <= sqrt(2 decel d_left): 1.5 m/s until 5.625 m before the end, then braking to 0
    line = StraightLine(x0=0.0, y0=0.0, x1=50.0, y1=0.0)
    assert target_speed(line, 50.0 - 5.7, SPEED, LIMITS) == 1.5
    for d in (5.0, 2.0, 0.5, 0.0):
        assert math.isclose(target_speed(line, 50.0 - d, SPEED, LIMITS), math.sqrt(0.4 * d))
    assert target_speed(line, 60.0, SPEED, LIMITS) == 0.0  # past it (the projection clamps)


def test_the_profile_ramps_up_from_the_vehicle_speed_and_slows_at_once() -> None:
    line = StraightLine(x0=0.0, y0=0.0, x1=200.0, y1=0.0)
    prof = SpeedProfile(SPEED, LIMITS)
    # from rest: the first command is the vehicle's speed, then + accel dt per call, whatever
    # the vehicle does meanwhile, until the cruise cap
    vs = [prof.command(0.1 * k, line, 0.0, 0.0) for k in range(100)]
    assert vs[0] == 0.0
    assert np.allclose(np.diff(vs[:75]), SPEED.accel_mps2 * 0.1)
    assert max(vs) == 1.5 and vs[-1] == 1.5
    # a gap in the calls (an outage) ramps by the time that passed, not by the call count
    prof.reset()
    assert prof.command(0.0, line, 0.0, 0.4) == 0.4  # a path taken under way: from its speed
    assert math.isclose(prof.command(2.0, line, 0.0, 0.4), 0.8)
    # a slow-down (the end of the path) takes effect at once, the ramp resumes from there
    assert math.isclose(prof.command(2.1, line, 199.0, 0.8), math.sqrt(0.4))
    assert math.isclose(prof.command(2.2, line, 10.0, 0.8), math.sqrt(0.4) + 0.02)
    # eq. (11): a cruise speed above v_max is capped
    fast = StraightLine(x0=0.0, y0=0.0, x1=200.0, y1=0.0, v_ref=9.0)
    prof.reset()
    assert prof.command(0.0, fast, 0.0, 2.0) == LIMITS.v_max


def test_a_path_taken_while_accelerating_carries_on_with_the_ramp() -> None:
    # the hull's speed lags the command: a new path taken a period after the last command
    # ramps on from that command, not from the (slower) vehicle; after a silence longer than
    # ramp_carry_s, or with ramp_carry_s = 0, from the vehicle's speed as before
    line = StraightLine(x0=0.0, y0=0.0, x1=200.0, y1=0.0)
    for carry, t_new, expected in ((0.5, 3.1, 0.62), (0.5, 4.0, 0.1), (0.0, 3.1, 0.1)):
        prof = SpeedProfile(replace(SPEED, ramp_carry_s=carry), LIMITS)
        for k in range(31):  # 0 .. 3.0 s: the command reaches 0.6 m/s
            prof.command(0.1 * k, line, 0.0, 0.0)
        prof.reset()  # a new path, the vehicle still at 0.1 m/s
        assert math.isclose(prof.command(t_new, line, 0.0, 0.1), expected)
    # a vehicle faster than the last command (a slow-down) starts from its own speed
    prof = SpeedProfile(SPEED, LIMITS)
    prof.command(0.0, line, 0.0, 0.3)
    prof.reset()
    assert prof.command(0.1, line, 0.0, 0.9) == 0.9


def test_the_course_over_ground_is_the_heading_crabbed_by_the_current() -> None:
    # a path taken in a current leaves along the course the controllers steer, not the hull's
    # heading: a hull crabbing 11.5 deg into a 0.3 m/s cross current at 1.5 m/s makes good
    # its path's heading; in still water with no sway the course is the heading, bit for bit
    crab = crab_angle((0.0, 0.3), 0.0, 1.5)
    assert math.isclose(math.degrees(crab), -11.54, abs_tol=0.01)
    assert abs(course_over_ground(crab, 1.5, 0.0, (0.0, 0.3))) < 1e-12
    assert course_over_ground(0.7, 1.5, 0.0, (0.0, 0.0)) == 0.7
    # sway to port turns the course to port; at rest the steerage speed is assumed
    assert course_over_ground(0.0, 1.0, 0.1, (0.0, 0.0)) > 0.0
    assert math.isclose(course_over_ground(0.0, 0.0, 0.0, (0.0, 0.5)), math.pi / 4)


@pytest.mark.parametrize("kind", ["nurbs", "backstepping", "fuzzy_pid"])
def test_every_controller_takes_its_speed_from_the_profile(kind: ControllerKind) -> None:
    # on the path, aligned, from rest: every controller commands the same ramp (speed is
    # shared, steering is the only difference), and never turns while the vehicle is still
    line = StraightLine(x0=0.0, y0=0.0, x1=200.0, y1=0.0)
    ctrl = make_controller(ControllerConfig(kind=kind), LIMITS)
    prof = SpeedProfile(SPEED, LIMITS)
    for k in range(30):
        pose = (0.1 * k, 0.5, -0.1, 0.0, 0.0)  # off the line and askew, at rest
        v, w = ctrl.command(0.1 * k, pose, line)
        assert v == prof.command(0.1 * k, line, 0.1 * k, 0.0)
        assert w == 0.0  # at v = 0 no yaw rate is possible: the cap is v / R_min = 0


def test_backstepping_never_overspeeds_past_the_profile() -> None:
    # a vehicle 4 m behind the virtual reference (e_x = 4 m) at cruise speed: the law's
    # v_r + k_x e_x = 3.5 m/s used to reach v_max = 2 m/s; now it is the profile's 1.5 m/s.
    # Ahead of it (e_x < 0), the law slows the vehicle down
    line = StraightLine(x0=0.0, y0=0.0, x1=200.0, y1=0.0)
    ctrl = Backstepping(ControllerConfig().backstepping, LIMITS)
    ctrl.command(0.0, (0.0, 0.0, 0.0, 1.5, 0.0), line)
    v, _ = ctrl.command(4.0 / 1.5, (0.0, 0.0, 0.0, 1.5, 0.0), line)
    assert math.isclose(ctrl.last_errors[0], 4.0) and v == 1.5
    ctrl.reset()
    v, _ = ctrl.command(0.0, (10.0, 0.0, 0.3, 1.5, 0.0), line)
    assert v < 1.5


def test_backstepping_on_the_reference_commands_the_feed_forward() -> None:
    # the vehicle exactly on the reference posture: v = v_r, w = v_r kappa (Kanayama eq. 6)
    ref = Circle(cx=0.0, cy=0.0, radius=8.0, v_ref=1.2)
    ctrl = Backstepping(ControllerConfig().backstepping, LIMITS)
    x, y = ref.point_at_s(0.0)
    v, w = ctrl.command(0.0, (x, y, ref.heading_at_s(0.0), 1.2, 0.15), ref)
    assert math.isclose(v, 1.2) and math.isclose(w, 1.2 / 8.0)
    # a vehicle that does not move: the virtual point stops max_lead_m = 5 m ahead
    for k in range(1, 200):
        ctrl.command(0.1 * k, (x, y, ref.heading_at_s(0.0), 0.0, 0.0), ref)
    e_x, _, _ = ctrl.last_errors
    assert e_x < 5.0 + 1e-9 and e_x > 4.0


_pose = st.tuples(
    st.floats(-60.0, 60.0),
    st.floats(-60.0, 60.0),
    st.floats(-10.0, 10.0),
    st.floats(0.0, 2.0),
    st.floats(-0.5, 0.5),
)


@settings(max_examples=80, deadline=None)
@given(st.lists(_pose, min_size=1, max_size=6), st.floats(0.0, 3.0), st.booleans())
def test_every_command_is_inside_eq11(
    poses: list[tuple[float, float, float, float, float]], latency: float, circle: bool
) -> None:
    # whatever the poses (jumping around, far off the path) and latency: eq. (11) holds,
    # every controller's turning radius is >= R_min at the pose's speed (delay compensation
    # keeps the speed) and the speed stays within the cruise cap
    ref: ArcLengthReference = (
        Circle(cx=0.0, cy=0.0, radius=8.0) if circle else StraightLine(x0=0, y0=0, x1=50, y1=5)
    )
    kinds: tuple[ControllerKind, ...] = ("nurbs", "backstepping", "fuzzy_pid")
    for kind in kinds:
        ctrl = make_controller(ControllerConfig(kind=kind), LIMITS)
        for k, pose in enumerate(poses):
            v, w = ctrl.command(0.1 * k, pose, ref, latency_s=latency)
            assert LIMITS.v_min <= v <= ref.v_ref and LIMITS.w_min <= w <= LIMITS.w_max
            assert abs(w) <= pose[3] / LIMITS.r_min + 1e-12


def test_saturate_and_factory() -> None:
    # eq. (11), and |w| <= v_now / R_min at the vehicle's speed (not the commanded one)
    assert LIMITS.saturate(9.0, -9.0, 9.0) == (LIMITS.v_max, LIMITS.w_min)
    assert LIMITS.saturate(1.5, 0.4, 1.0) == (1.5, 1.0 / LIMITS.r_min)
    assert LIMITS.saturate(1.5, -0.4, 0.0) == (1.5, 0.0)  # at rest: no turn at all
    assert LIMITS.saturate(1.5, -0.4, math.nan) == (1.5, 0.0)
    assert LIMITS.saturate(math.nan, 0.1, 1.0) == (0.0, 0.0)  # a non-finite law output stops
    assert LIMITS.turn_cap(1.5) == 0.3 and LIMITS.turn_cap(-1.0) == 0.0
    # delay compensation and the speed profile: one setting for every controller
    for comp in (True, False):
        speed = SpeedConfig(accel_mps2=0.1)
        kinds: tuple[ControllerKind, ...] = ("nurbs", "backstepping", "fuzzy_pid")
        built = [
            make_controller(ControllerConfig(kind=k, delay_compensation=comp, speed=speed), LIMITS)
            for k in kinds
        ]
        assert [type(c) for c in built] == [NurbsTracker, Backstepping, ImmuneFuzzyPid]
        for c in built:
            assert isinstance(c, NurbsTracker | Backstepping | ImmuneFuzzyPid)
            assert c.compensate_delay is comp and c.speed.cfg is speed


def test_config_validation_names_the_field() -> None:
    with pytest.raises(ValueError, match="^kind:"):
        ControllerConfig(kind="pid")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="^curvature_budget:"):
        SpeedConfig(curvature_budget=0.0)
    with pytest.raises(ValueError, match="^accel_mps2:"):
        SpeedConfig(accel_mps2=0.0)
    with pytest.raises(ValueError, match="^decel_mps2:"):
        SpeedConfig(decel_mps2=-1.0)
    with pytest.raises(ValueError, match="^lookahead_m:"):
        NurbsGains(lookahead_m=0.0)
    with pytest.raises(ValueError, match="^immune_eta:"):
        FuzzyPidGains(immune_eta=1.0)
    with pytest.raises(ValueError, match="^v_min_mps:"):
        VehicleConfig(v_min_mps=2.5)
    with pytest.raises(ValueError, match="^turn_radius_min_m:"):
        VehicleConfig(turn_radius_min_m=1.0)  # 1.5 m/s on 1 m needs 1.5 rad/s > 0.5
