"""Estimator fusion at sampling time: delayed, reordered, too-old and duplicated measurements."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from common.config.estimator import EstimatorConfig
from common.config.sensor import SensorConfig
from common.messages import (
    Detection,
    Message,
    NavFix,
    ObstacleDetections,
    StateEstimate,
    TruthState,
)
from common.runtime.model.core import Delivery
from services.control.controllers import predict_pose
from services.estimator import EstimatorCore
from services.estimator.core import DETECTION_BUDGET, FIX_BUDGET
from services.sensor.models import nav_fix

START = (5.0, 20.0, 0.0)
V, W = 1.5, 0.1  # truth: a steady turn


def _truth(t: float) -> TruthState:
    th = W * t
    x = START[0] + V / W * math.sin(th)
    y = START[1] + V / W * (1.0 - math.cos(th))
    return TruthState(stamp=t, x=x, y=y, theta=th, v=V, w=W)


def _fixes(n: int, seed: int = 1) -> list[NavFix]:
    rng = np.random.default_rng(seed)
    cfg = SensorConfig()
    return [nav_fix(_truth(round(0.1 * k, 9)), cfg, rng.standard_normal(4)) for k in range(n)]


def _scans(n: int, seed: int = 2) -> list[ObstacleDetections]:
    """Two obstacles at constant velocity, 5 Hz scans, one of them missed now and then."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        t = round(0.2 * k, 9)
        dets = []
        for oid, (x0, y0, vx, vy) in ((3, (30.0, 10.0, 0.5, 0.2)), (8, (40.0, 30.0, -0.3, 0.0))):
            z = rng.standard_normal(3)
            if rng.random() < 0.9:
                dets.append(
                    Detection(
                        id=oid,
                        x=x0 + vx * t + 0.2 * z[0],
                        y=y0 + vy * t + 0.2 * z[1],
                        radius=1.0 + 0.1 * z[2],
                        std_xy=0.2,
                        std_radius=0.1,
                    )
                )
        out.append(ObstacleDetections(stamp=t, detections=tuple(dets)))
    return out


def _deliver(core: EstimatorCore, msg: Message, t: float) -> None:
    stream = "nav" if isinstance(msg, NavFix) else "obstacles"
    core.deliver(Delivery(source="sensor", stream=stream, msg=msg, t=t))


def _outputs(core: EstimatorCore, t: float) -> np.ndarray:
    """Everything published at t as one vector: state, covariance, every track field."""
    state, tracks = (e.msg for e in core.step(t))
    vals = [state.x, state.y, state.theta, state.v, state.w, *state.covariance]  # type: ignore[attr-defined]
    for tr in tracks.tracks:  # type: ignore[attr-defined]
        vals += [tr.id, tr.x, tr.y, tr.vx, tr.vy, tr.ax, tr.ay, tr.radius, *tr.covariance]
    return np.array(vals)


CONFIGS = [
    EstimatorConfig(),
    EstimatorConfig(vehicle_filter="ukf"),
    EstimatorConfig(prefilter="mean+lag"),
]


@pytest.mark.parametrize("cfg", CONFIGS, ids=["ekf", "ukf", "ekf-mean+lag"])
@pytest.mark.parametrize("later_fixes", [True, False])
def test_delayed_300ms_equals_on_time(cfg: EstimatorConfig, later_fixes: bool) -> None:
    """A fix and a scan stamped 2.0 s arrive at 2.3 s: from then on the outputs equal those
    of on-time fusion (then prediction), to 1e-9. With later_fixes the fixes of 2.1-2.3 s
    arrive on time first, so the late ones are fused by rolling back and re-fusing.
    """
    fixes, scans = _fixes(60), _scans(30)
    n_fix = 60 if later_fixes else 21  # without later fixes the stream stops at 2.0 s
    n_scan = 30 if later_fixes else 11
    on_time = EstimatorCore(cfg, START)
    late = EstimatorCore(cfg, START)
    late_fix, late_scan = fixes[20], scans[10]  # both stamped 2.0
    differed = False
    for k in range(60):
        t = round(0.1 * k, 9)
        arriving: list[Message] = [f for f in fixes[:n_fix] if f.stamp == t]
        arriving += [s for s in scans[:n_scan] if s.stamp == t]
        for msg in arriving:
            _deliver(on_time, msg, t)
            if msg is not late_fix and msg is not late_scan:
                _deliver(late, msg, t)
        if t == 2.3:
            _deliver(late, late_fix, t)
            _deliver(late, late_scan, t)
        a, b = _outputs(on_time, t), _outputs(late, t)
        if t < 2.3:
            differed |= a.shape != b.shape or not np.allclose(a, b, rtol=0, atol=1e-9)
        else:
            assert a.shape == b.shape
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-9, err_msg=f"t={t}")
    assert differed  # the delayed fix did matter before it arrived
    assert late.counters["nav_replays"] == (1 if later_fixes else 0)


N_FIXES, N_SCANS = 16, 6
# Delivered in one step, in reverse each message replays those stamped after it: at most
# n (n + 1) / 2 fusions of fixes, and of scans of up to two detections each. Within the
# estimator's per-step budgets, or a replay is rejected (over_budget) by design: 8 scans in
# reverse order cost ~72 detections, and a near-reversed draw failed this test.
assert N_FIXES * (N_FIXES + 1) // 2 <= FIX_BUDGET
assert 2 * N_SCANS * (N_SCANS + 1) // 2 <= DETECTION_BUDGET


@settings(max_examples=25, deadline=None)
@given(
    order=st.permutations(list(range(N_FIXES + N_SCANS))),
    cfg=st.sampled_from(CONFIGS),
)
def test_arrival_order_within_buffer_does_not_matter(
    order: list[int], cfg: EstimatorConfig
) -> None:
    # 16 fixes over 1.5 s and 6 scans over 1.0 s, inside history_s = 2 s
    msgs: list[Message] = [*_fixes(N_FIXES, seed=5), *_scans(N_SCANS, seed=6)]
    in_order = EstimatorCore(cfg, START)
    for m in sorted(msgs, key=lambda m: m.stamp):
        _deliver(in_order, m, 1.6)
    shuffled = EstimatorCore(cfg, START)
    for i in order:
        _deliver(shuffled, msgs[i], 1.6)
    for t in (1.6, 2.5):
        np.testing.assert_allclose(_outputs(shuffled, t), _outputs(in_order, t), rtol=0, atol=1e-9)
    counts = shuffled.counters
    assert counts["nav_fused"] == N_FIXES and counts["scans_fused"] == N_SCANS, counts


def test_measurements_older_than_history_are_rejected_and_counted() -> None:
    cfg = EstimatorConfig(history_s=2.0)
    core = EstimatorCore(cfg, START)
    fixes = _fixes(101)
    for f in fixes[21:]:  # stamps 2.1 .. 10.0
        _deliver(core, f, f.stamp)
    before = _outputs(core, 10.0)
    _deliver(core, fixes[20], 10.0)  # stamp 2.0: 8 s older than the newest
    assert core.counters["nav_rejected_old"] == 1
    np.testing.assert_array_equal(_outputs(core, 10.0), before)
    old = ObstacleDetections(stamp=7.5, detections=())
    _deliver(core, ObstacleDetections(stamp=10.0, detections=()), 10.0)
    _deliver(core, old, 10.0)
    assert core.counters["scans_rejected_old"] == 1
    # 1.9 s old is still inside the window: fused by a replay
    shifted = nav_fix(_truth(8.15), SensorConfig(), np.zeros(4))
    _deliver(core, shifted, 10.0)
    assert core.counters["nav_replays"] == 1 and core.counters["nav_rejected_old"] == 1


def test_duplicates_are_dropped() -> None:
    once = EstimatorCore(EstimatorConfig(), START)
    twice = EstimatorCore(EstimatorConfig(), START)
    fixes, scans = _fixes(10), _scans(5)
    for m in [*fixes, *scans]:
        _deliver(once, m, 1.0)
        _deliver(twice, m, 1.0)
        _deliver(twice, m, 1.0)  # a network duplicate: same stamp, same seq
    np.testing.assert_array_equal(_outputs(twice, 1.0), _outputs(once, 1.0))
    assert twice.counters["nav_duplicates"] == 10
    assert twice.counters["scans_duplicates"] == 5


def test_estimate_is_predicted_to_step_time() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    for f in _fixes(51):  # up to 5.0 s
        _deliver(core, f, f.stamp)
    x5 = _outputs(core, 5.0)
    x6 = _outputs(core, 6.0)  # no fix since 5.0 s: dead-reckoned one second ahead
    assert math.hypot(x6[0] - x5[0], x6[1] - x5[1]) == pytest.approx(V * 1.0, rel=0.05)
    truth6 = _truth(6.0)
    assert math.hypot(x6[0] - truth6.x, x6[1] - truth6.y) < 0.3
    assert x6[5] > x5[5]  # var(x) grew


def test_an_estimate_says_how_far_it_was_carried_past_its_newest_fix() -> None:
    # the planner goes back along that arc to the fix and predicts from there with the
    # commands it sent (issue 16): a late fix is old information whatever the stamp says
    core = EstimatorCore(EstimatorConfig(), START)
    state = core.step(0.5)[0].msg
    # no fix yet: the start pose, as it was at mission time 0 (a late-started estimator's
    # start pose is as old as the mission, and a planner takes it as stale)
    assert isinstance(state, StateEstimate) and state.predicted_s == 0.5
    for f in _fixes(31):  # up to 3.0 s
        _deliver(core, f, f.stamp + 1.0)  # each a second late
    state = core.step(4.0)[0].msg
    assert isinstance(state, StateEstimate)
    assert (state.stamp, state.predicted_s) == (4.0, pytest.approx(1.0))
    # going back by predicted_s at its constant twist lands on the fused state at the fix
    pose = (state.x, state.y, state.theta, state.v, state.w)
    x, y, *_ = predict_pose(pose, -state.predicted_s, (state.current_x, state.current_y))
    fused = core.nav.state.x
    # (to the hull's sway, which the estimate does not carry and which decays meanwhile)
    assert (x, y) == pytest.approx((fused[0], fused[1]), abs=5e-3)
