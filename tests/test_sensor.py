"""Sensor core: fix noise statistics, FOV/range, detection rate, stamps, rates, determinism."""

from __future__ import annotations

import math

import numpy as np
import pytest
from helpers.planner_world import default_scenario

from common.config.sensor import SensorConfig
from common.config.world import CircleObstacleConfig, MovingObstacleConfig, WorldConfig
from common.messages import NavFix, ObstacleDetections, TruthState
from common.runtime.model.core import Delivery, Emit
from common.scalar import wrap_angle
from common.world import World
from services.sensor import SensorCore
from services.sensor.models import in_view


def _truth(
    t: float, x: float = 50.0, y: float = 20.0, th: float = 0.0, v: float = 1.5
) -> TruthState:
    return TruthState(stamp=t, x=x, y=y, theta=th, v=v, w=0.0)


def _run(
    core: SensorCore, n_steps: int, lag_s: float = 0.05, th: float = 0.0
) -> tuple[list[NavFix], list[ObstacleDetections], list[TruthState]]:
    """Step n_steps; before each step deliver a truth sampled lag_s earlier (bus delay)."""
    navs: list[NavFix] = []
    scans: list[ObstacleDetections] = []
    truths: list[TruthState] = []
    dt = core.cfg.period_s
    for k in range(n_steps):
        t = k * dt
        tr = _truth(t - lag_s, x=50.0 + 0.01 * k, th=th)
        truths.append(tr)
        core.deliver(Delivery(source="vehicle", stream="truth", msg=tr, t=t))
        out: list[Emit] = core.step(t)
        navs += [e.msg for e in out if isinstance(e.msg, NavFix)]
        scans += [e.msg for e in out if isinstance(e.msg, ObstacleDetections)]
    return navs, scans, truths


def test_fix_noise_statistics_and_stamps() -> None:
    cfg = SensorConfig(obstacle_rate_hz=1.0, nav_rate_hz=10.0)
    core = SensorCore(cfg, World(WorldConfig()), np.random.default_rng(1))
    navs, _, truths = _run(core, 5000)
    assert len(navs) == 5000
    by_stamp = {tr.stamp: tr for tr in truths}
    assert all(f.stamp in by_stamp for f in navs)  # each fix carries its truth's stamp
    assert navs[7].stamp == truths[7].stamp == pytest.approx(0.7 - 0.05)
    err = np.array(
        [
            (
                f.x - by_stamp[f.stamp].x,
                f.y - by_stamp[f.stamp].y,
                wrap_angle(f.heading - by_stamp[f.stamp].theta),
                f.speed - by_stamp[f.stamp].v,
            )
            for f in navs
        ]
    )
    std = np.array(
        [cfg.nav_std_xy_m, cfg.nav_std_xy_m, cfg.nav_std_heading_rad, cfg.nav_std_speed_mps]
    )
    n = len(err)
    # mean within 4 standard errors; std within 5 % (its standard error is ~1 % at n = 5000)
    assert np.all(np.abs(err.mean(axis=0)) < 4.0 * std / math.sqrt(n))
    assert np.all(np.abs(err.std(axis=0) / std - 1.0) < 0.05)
    assert all(-math.pi <= f.heading < math.pi for f in navs)
    assert (navs[0].std_xy, navs[0].std_heading, navs[0].std_speed) == tuple(std[[0, 2, 3]])


def test_heading_wraps_near_pi() -> None:
    cfg = SensorConfig(nav_std_heading_rad=0.3)
    core = SensorCore(cfg, World(WorldConfig()), np.random.default_rng(2))
    navs, _, _ = _run(core, 400, th=math.pi - 0.01)
    heads = np.array([f.heading for f in navs])
    assert np.all((heads >= -math.pi) & (heads < math.pi))
    assert np.any(heads < 0.0) and np.any(heads > 0.0)  # noise crossed +-pi, and was wrapped


def _ring_world() -> World:
    """36 small obstacles on two rings around (50, 20): radii 8 m and 18 m."""
    circles = []
    for i in range(18):
        a = 2.0 * math.pi * i / 18.0
        for j, rr in enumerate((8.0, 18.0)):
            circles.append(
                CircleObstacleConfig(
                    id=2 * i + j,
                    x_m=50.0 + rr * math.cos(a),
                    y_m=20.0 + 0.9 * rr * math.sin(a),
                    radius_m=0.5,
                )
            )
    return World(WorldConfig(circles=tuple(circles)))


def test_fov_range_and_detection_rate() -> None:
    cfg = SensorConfig(det_range_m=12.0, det_fov_half_angle_rad=1.0, p_detect=0.7)
    world = _ring_world()
    core = SensorCore(cfg, world, np.random.default_rng(3))
    detected = seen = 0
    for k in range(2000):
        t = 0.1 * k
        th = wrap_angle(0.37 * k)  # sweep the heading around
        tr = TruthState(stamp=t, x=50.0, y=20.0, theta=th, v=0.0, w=0.0)
        core.deliver(Delivery(source="vehicle", stream="truth", msg=tr, t=t))
        for e in core.step(t):
            if not isinstance(e.msg, ObstacleDetections):
                continue
            visible = {o.id for o in world.obstacles_at(t) if in_view(o, 50.0, 20.0, th, cfg)}
            ids = {d.id for d in e.msg.detections}
            assert ids <= visible  # nothing outside the sector is ever reported
            for d in e.msg.detections:
                o = next(o for o in world.obstacles_at(t) if o.id == d.id)
                dist = math.hypot(o.x - 50.0, o.y - 20.0)
                assert dist - o.radius <= cfg.det_range_m
                bearing = abs(wrap_angle(math.atan2(o.y - 20.0, o.x - 50.0) - th))
                assert bearing <= cfg.det_fov_half_angle_rad
                assert abs(d.x - o.x) < 6 * cfg.det_std_xy_m
            detected += len(ids)
            seen += len(visible)
    assert seen > 1000
    rate = detected / seen
    # binomial: within 4 standard errors of p_detect
    assert abs(rate - cfg.p_detect) < 4.0 * math.sqrt(cfg.p_detect * (1 - cfg.p_detect) / seen)


def test_sector_edges() -> None:
    cfg = SensorConfig(det_range_m=10.0, det_fov_half_angle_rad=0.5)
    w = World(
        WorldConfig(
            circles=(
                CircleObstacleConfig(id=1, x_m=60.5, y_m=20.0, radius_m=0.5),  # surface at 10 m
                CircleObstacleConfig(id=2, x_m=60.6, y_m=20.0, radius_m=0.5),  # 10.1 m: out
                CircleObstacleConfig(id=3, x_m=40.0, y_m=20.0, radius_m=1.0),  # behind
                CircleObstacleConfig(
                    id=4, x_m=50 + 5 * math.cos(0.49), y_m=20 + 5 * math.sin(0.49), radius_m=0.3
                ),  # just inside the half-angle
                CircleObstacleConfig(
                    id=5, x_m=50 + 5 * math.cos(0.51), y_m=20 + 5 * math.sin(0.51), radius_m=0.3
                ),  # just outside
            )
        )
    )
    seen = {o.id for o in w.obstacles_at(0.0) if in_view(o, 50.0, 20.0, 0.0, cfg)}
    assert seen == {1, 4}


def test_rates_and_integer_tick_schedule() -> None:
    cfg = SensorConfig(nav_rate_hz=10.0, obstacle_rate_hz=2.5)
    core = SensorCore(cfg, World(default_scenario().world), np.random.default_rng(4))
    navs, scans, _ = _run(core, 1000)  # 100 s
    assert len(navs) == 1000 and len(scans) == 250
    with pytest.raises(ValueError, match="obstacle_rate_hz"):
        SensorConfig(nav_rate_hz=10.0, obstacle_rate_hz=3.0)
    with pytest.raises(ValueError, match="p_detect"):
        SensorConfig(p_detect=1.5)


def test_no_truth_no_output_and_stale_truth_not_resampled() -> None:
    core = SensorCore(SensorConfig(), World(default_scenario().world), np.random.default_rng(5))
    assert core.step(0.0) == []
    core.deliver(Delivery(source="vehicle", stream="truth", msg=_truth(0.0), t=0.0))
    assert {e.stream for e in core.step(0.0)} == {"nav", "obstacles"}
    assert core.step(0.1) == []  # same truth: no second sample of the same instant
    assert core.stale_skips == 1


def test_same_seed_identical_and_draws_independent_of_visibility() -> None:
    world = World(default_scenario().world)
    a = _run(SensorCore(SensorConfig(), world, np.random.default_rng(7)), 300)
    b = _run(SensorCore(SensorConfig(), world, np.random.default_rng(7)), 300)
    assert a[0] == b[0] and a[1] == b[1]
    c = _run(SensorCore(SensorConfig(), world, np.random.default_rng(8)), 300)
    assert a[0] != c[0]
    # facing away from every obstacle changes what is seen, not the later nav noise
    d = _run(SensorCore(SensorConfig(), world, np.random.default_rng(7)), 300, th=math.pi)
    assert sum(len(s.detections) for s in a[1]) != sum(len(s.detections) for s in d[1])
    assert [(f.x, f.y, f.speed) for f in a[0]] == [(f.x, f.y, f.speed) for f in d[0]]


def test_detections_of_moving_obstacle_at_sampling_time() -> None:
    m = MovingObstacleConfig(id=9, kind="line", radius_m=1.0, x0_m=60, y0_m=20, vx_mps=2.0)
    cfg = SensorConfig(det_std_xy_m=0.0, det_std_radius_m=0.0, p_detect=1.0)
    core = SensorCore(cfg, World(WorldConfig(moving=(m,))), np.random.default_rng(9))
    core.deliver(Delivery(source="vehicle", stream="truth", msg=_truth(3.0), t=3.4))
    (scan,) = [e.msg for e in core.step(3.4) if isinstance(e.msg, ObstacleDetections)]
    assert scan.stamp == 3.0
    (d,) = scan.detections
    assert (d.id, d.x, d.y, d.radius) == (9, 66.0, 20.0, 1.0)  # the world at t = 3.0, not 3.4
