"""Escape from contact (issue 14, defect 5): a start whose hull touches an obstacle gets a path out.

Oracles are independent of the planner's own clearance code: the world model's eq. (12)
(`World.clearance`, the one the vehicle simulation and `tidelink check` use) on dense samples.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers.planner_world import circle, default_scenario, polygon

from common.config.planner import PlannerConfig
from common.config.world import WorldConfig
from common.world import ObstacleState, World
from services.planner.clearance import StaticField
from services.planner.controllers.base import Limits
from services.planner.controllers.turn_on_spot import DONE_RAD, TurnOnSpot
from services.planner.escape import find_escapes
from services.planner.nurbs_curve import NurbsCurve, averaged_knots, curvature, join
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D, plan_path

CFG = PlannerConfig()
SCENARIO = default_scenario()
WORLD_CFG = SCENARIO.world
WORLD = World(WorldConfig(circles=WORLD_CFG.circles, polygons=WORLD_CFG.polygons))
R = SCENARIO.vehicle.radius_m  # 0.8 m
R_MIN = SCENARIO.vehicle.turn_radius_min_m  # 5 m
GOAL = Pose2D(x=95.0, y=20.0, theta=0.0)
STATIC = Obstacles(circles=WORLD_CFG.circles, polygons=WORLD_CFG.polygons)
# circle 1 is (20, 20) with radius 4: x = 15.5 puts the 0.8 m hull 0.3 m into it (issue 14)
IN_CONTACT = (15.5, 20.0)


def _request(x: float, y: float, theta: float, obstacles: Obstacles = STATIC) -> PlanRequest:
    return PlanRequest(
        start=Pose2D(x=x, y=y, theta=theta),
        goal=GOAL,
        area=WORLD_CFG.area,
        obstacles=obstacles,
        vehicle_radius_m=R,
        r_min_m=R_MIN,
        v_ref_mps=SCENARIO.vehicle.cruise_speed_mps,
    )


def _dense(res: PlanResult, n: int = 6000) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Points (n, 2), arc length (n,) and unsigned curvature (n,) of the planned curve."""
    curve = res.curve()
    u = np.linspace(curve.u_min, curve.u_max, n)
    pts, d1, d2 = curve.evaluate(u, 2)
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    return pts, s, curvature(d1, d2)


def _hull_clearance(pts: np.ndarray) -> np.ndarray:
    return WORLD.clearance_many(pts[:, 0], pts[:, 1], R, 0.0)


@pytest.mark.parametrize(
    ("theta", "turns"),
    [
        pytest.param(math.pi / 2, False, id="heading along the surface: straight ahead"),
        pytest.param(math.pi, False, id="heading away: straight ahead"),
        pytest.param(0.0, True, id="heading into the obstacle: turn on the spot first"),
        pytest.param(-0.3, True, id="heading into it, askew"),
    ],
)
def test_a_start_in_contact_gets_a_path_out_that_never_goes_deeper(
    theta: float, turns: bool
) -> None:
    req = _request(*IN_CONTACT, theta)
    assert _hull_clearance(np.array([IN_CONTACT]))[0] == pytest.approx(-0.3)  # in contact
    res = plan_path(req, CFG)
    assert res.status == "OK", res.reason
    assert "start in contact (hull clearance -0.30 m)" in res.reason
    pts, s, k = _dense(res)
    assert pts[0] == pytest.approx(IN_CONTACT, abs=1e-9)  # the path starts at the vehicle
    d = _hull_clearance(pts)
    esc = s <= res.escape_m - 0.05
    # the escape: straight (eq. (20) trivially), the hull never deeper, out within ~4 m
    assert k[esc].max() < 1e-6
    assert np.all(np.diff(d[esc]) >= -1e-9)
    assert 0.0 < res.escape_m < CFG.escape_len_m + CFG.rho0_m + 0.3 + 1e-9
    # past it, the plan keeps rho0 from every static obstacle (eq. (12)) ...
    assert d[s >= res.escape_m].min() >= CFG.rho0_m - 1e-6
    # ... and the whole path keeps the turning radius: kappa < 1 / R_min (eq. (20))
    assert k.max() < 1.0 / R_MIN
    # the path leaves along the heading unless it had to turn on the spot first
    leave = math.atan2(*(pts[1] - pts[0])[::-1])
    assert (res.turn_rad != 0.0) is turns
    assert math.remainder(leave - (theta + res.turn_rad), math.tau) == pytest.approx(0.0, abs=1e-6)


def test_the_way_out_is_the_shortest_when_the_heading_does_not_matter() -> None:
    # centre inside circle 1 (hull clearance -4.8 m): every direction is a normal; along the
    # heading it takes r + rho0 + 4 m (+ 1 cm beyond) to leave the margin, with no turn
    esc, *_ = find_escapes(
        Pose2D(x=20.0, y=20.0, theta=0.0),
        StaticField.build(WORLD_CFG.circles, WORLD_CFG.polygons),
        (),
        WORLD_CFG.area,
        r=R,
        rho0=CFG.rho0_m,
        r_min=R_MIN,
        v_ref=1.5,
        accel_horizon_s=CFG.accel_horizon_s,
        max_len_m=10.0,
    )
    assert esc.turn_rad == 0.0
    assert esc.length_m == pytest.approx(4.0 + R + CFG.rho0_m + 0.01, abs=0.05)
    assert esc.start_clearance_m == pytest.approx(-4.8)
    assert esc.end_clearance_m == pytest.approx(CFG.rho0_m, abs=0.06)
    free = esc.free
    assert WORLD.clearance(free.x, free.y, R, 0.0) == pytest.approx(esc.end_clearance_m)


def test_a_way_out_avoids_what_lies_behind_the_obstacle() -> None:
    # in contact with the lower circle, heading into it; a second circle sits 1.5 m above it,
    # so the way straight out (up, the lower circle's normal) soon gets nearer the upper one
    # than the vehicle was to the lower: the escape must go sideways, between the two
    lower = circle(id=1, x=50.0, y=16.0, radius=3.0)
    upper = circle(id=2, x=50.0, y=23.5, radius=3.0)
    static = StaticField.build((lower, upper), ())
    start = Pose2D(x=50.0, y=19.5, theta=-math.pi / 2)  # hull 0.3 m into the lower circle
    escapes = find_escapes(
        start,
        static,
        (),
        WORLD_CFG.area,
        r=R,
        rho0=CFG.rho0_m,
        r_min=R_MIN,
        v_ref=1.5,
        accel_horizon_s=CFG.accel_horizon_s,
        max_len_m=6.0,
    )
    assert escapes
    world = World(WorldConfig(circles=(lower, upper)))
    for esc in escapes:
        h = esc.heading
        s = np.linspace(0.0, esc.length_m, 200)
        d = world.clearance_many(start.x + s * math.cos(h), start.y + s * math.sin(h), R, 0.0)
        assert np.all(d >= d[0] - 1e-9)  # never deeper, whichever obstacle is nearer
        assert d[-1] > 0.0  # and the hull is free at its end
    best = escapes[0]
    assert abs(math.cos(best.heading)) > 0.9  # sideways
    assert best.end_clearance_m >= CFG.rho0_m  # out of the margin of both


def test_a_start_heading_at_an_obstacle_turns_on_the_spot_instead_of_stopping_for_good() -> None:
    # outside the margin (hull 1.03 m from circle 1) but heading at it: no curve within R_min
    # leaves along that heading, so the plan turns on the spot first (it was NO_PATH forever)
    req = _request(17.0, 15.0, 0.5)
    res = plan_path(req, CFG)
    assert res.ok, res.reason
    assert res.turn_rad != 0.0 and "turn" in res.reason
    pts, s, k = _dense(res)
    assert pts[0] == pytest.approx((17.0, 15.0))
    assert k.max() < 1.0 / R_MIN
    assert _hull_clearance(pts).min() >= CFG.rho0_m - 1e-6


def test_a_walled_off_goal_from_a_start_in_contact_is_still_no_path_and_says_why() -> None:
    wall = polygon(((60.0, 0.0), (62.0, 0.0), (62.0, 40.0), (60.0, 40.0)), id=20)
    walled = Obstacles(circles=WORLD_CFG.circles, polygons=(*WORLD_CFG.polygons, wall))
    res = plan_path(_request(*IN_CONTACT, math.pi / 2, walled), CFG)
    assert res.status == "NO_PATH"
    assert "start in contact" in res.reason and "goal unreachable" in res.reason


def test_join_is_the_two_curves_one_after_the_other() -> None:
    rng = np.random.default_rng(3)
    a_pts = np.cumsum(rng.normal(size=(6, 2)), axis=0)
    b_pts = a_pts[-1] + np.cumsum(rng.normal(size=(8, 2)), axis=0)
    b_pts[0] = a_pts[-1]
    a = NurbsCurve(3, a_pts, rng.uniform(0.5, 2.0, 6), averaged_knots(a_pts, 3))
    b = NurbsCurve(3, b_pts, rng.uniform(0.5, 2.0, 8), averaged_knots(b_pts, 3))
    c = join(a, b, 0.3)
    u = np.linspace(0.0, 1.0, 101)
    assert c.evaluate(0.3 * u, 0)[0] == pytest.approx(a.evaluate(u, 0)[0], abs=1e-12)
    assert c.evaluate(0.3 + 0.7 * u, 0)[0] == pytest.approx(b.evaluate(u, 0)[0], abs=1e-12)
    with pytest.raises(ValueError, match="must end where the second starts"):
        join(b, a, 0.5)


def test_turn_on_the_spot_reaches_the_heading_with_a_small_overshoot() -> None:
    lim = Limits(v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5, r_min=R_MIN)
    tau = SCENARIO.vehicle.yaw_tau_s
    turn = TurnOnSpot(heading=math.pi / 2, limits=lim, yaw_tau_s=tau)
    theta, w, dt, t = 0.0, 0.0, 0.01, 0.0
    peak = 0.0
    while (cmd := turn.command((0.0, 0.0, theta, 0.0, w))) is not None:
        v_cmd, w_cmd = cmd
        assert v_cmd == 0.0 and lim.w_min <= w_cmd <= lim.w_max  # eq. (11), on the spot
        w += dt * (w_cmd - w) / tau  # the vehicle's first-order yaw response
        theta += dt * w
        peak = max(peak, theta)
        t += dt
        assert t < 30.0
    assert abs(theta - math.pi / 2) <= DONE_RAD
    # a 90 degree turn at up to 0.5 rad/s: a few seconds, not a spin
    assert t < 8.0 and peak < math.pi / 2 + 0.05 * math.pi / 2


def test_a_vehicle_that_coasted_out_of_the_area_is_led_back_in() -> None:
    # hull 1.5 m beyond the southern edge, heading south-east (a hold that kept its heading)
    req = _request(64.8, -0.7, -0.9)
    res = plan_path(req, CFG)
    assert res.ok, res.reason
    assert "start outside the area (hull 1.50 m beyond its edge)" in res.reason
    pts, s, k = _dense(res)
    edge = np.minimum(pts[:, 1] - WORLD_CFG.area.y_min_m, WORLD_CFG.area.y_max_m - pts[:, 1])
    back = s <= res.escape_m - 0.05
    assert np.all(np.diff(edge[back]) >= -1e-9)  # never farther out on the way back
    assert edge[s >= res.escape_m].min() >= R - 1e-9  # then the hull stays in (eq. (10))
    assert _hull_clearance(pts).min() >= CFG.rho0_m - 1e-6  # and nothing comes near
    assert k.max() < 1.0 / R_MIN


def test_a_way_out_is_never_empty_when_a_moving_obstacle_draws_off() -> None:
    # a moving disc in contact, heading off at 1 m/s: during a turn on the spot it leaves,
    # so a turned candidate is clear where it starts; the way out is still a segment
    mover = ObstacleState(
        id=9, x=50.0, y=22.5, vx=0.0, vy=1.0, ax=0.0, ay=0.0, radius=2.0, moving=True
    )
    start = Pose2D(x=50.0, y=20.0, theta=math.pi / 2)  # heading into it, hull 0.3 m in
    escapes = find_escapes(
        start,
        StaticField.build((), ()),
        (mover,),
        WORLD_CFG.area,
        r=R,
        rho0=CFG.rho0_m,
        r_min=R_MIN,
        v_ref=1.5,
        accel_horizon_s=CFG.accel_horizon_s,
        max_len_m=5.0,
    )
    assert escapes and all(e.length_m > 0.0 for e in escapes)
    req = _request(50.0, 20.0, math.pi / 2, Obstacles(moving=(mover,)))
    assert plan_path(req, CFG).ok


def test_a_vehicle_still_under_way_stops_straight_before_it_turns() -> None:
    lim = Limits(v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5, r_min=R_MIN)
    turn = TurnOnSpot(heading=math.pi, limits=lim, yaw_tau_s=0.5)
    # turning at 1 m/s would sweep an arc of radius v / w: stop first (the hull is a disc,
    # so only a turn in place cannot bring it nearer anything)
    assert turn.command((0.0, 0.0, 0.0, 1.0, 0.0)) == (0.0, 0.0)
    v, w = turn.command((0.0, 0.0, 0.0, 0.05, 0.0)) or (math.nan, math.nan)
    assert v == 0.0 and w == lim.w_max
    assert turn.command((0.0, 0.0, math.pi - 0.05, 1.0, 0.0)) is None  # facing it: done


def _random_start(rng: np.random.Generator, kind: int) -> tuple[float, float]:
    """A start in contact (0), inside the margin (1), off the area's southern edge (2)."""
    while True:
        x, y = rng.uniform(2.0, 75.0), rng.uniform(-1.5, 39.0)
        d = WORLD.clearance(x, y, R, 0.0)
        edge = y - WORLD_CFG.area.y_min_m - R
        if (kind, d <= 0.0, 0.0 < d < CFG.rho0_m, edge < 0.0 and d > 0.0) in {
            (0, True, False, False),
            (1, False, True, False),
            (2, False, False, True),
        }:
            return x, y


def test_any_start_in_contact_in_the_margin_or_off_the_area_plans_safely_or_says_why() -> None:
    # seeded random starts of each kind, with a moving obstacle about: plan_path never
    # raises, and an OK path starts at the vehicle, keeps rho0 past its escape (static
    # obstacles, the world's eq. (12)), keeps the hull in the area and kappa < 1 / R_min
    rng = np.random.default_rng(14)
    mover = ObstacleState(
        id=10, x=40.0, y=30.0, vx=0.0, vy=-0.5, ax=0.0, ay=0.0, radius=1.5, moving=True
    )
    obstacles = Obstacles(circles=WORLD_CFG.circles, polygons=WORLD_CFG.polygons, moving=(mover,))
    area = WORLD_CFG.area
    ok = 0
    for i in range(36):
        x, y = _random_start(rng, i % 3)
        res = plan_path(_request(x, y, rng.uniform(-math.pi, math.pi), obstacles), CFG)
        if not res.ok:
            assert res.reason
            continue
        ok += 1
        pts, s, k = _dense(res)
        assert pts[0] == pytest.approx((x, y), abs=1e-9)
        after = s >= res.escape_m
        assert _hull_clearance(pts[after]).min() >= CFG.rho0_m - 1e-6
        assert pts[after, 0].min() >= area.x_min_m + R - 1e-6
        assert pts[after, 1].min() >= area.y_min_m + R - 1e-6
        assert pts[after, 1].max() <= area.y_max_m - R + 1e-6
        assert k.max() < 1.0 / R_MIN
    assert ok >= 34, ok  # 36 of 36 when written; none before (contact, off the area)
