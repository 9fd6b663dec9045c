"""The estimator against hostile or absurd inputs (issue 14, defect 2): a fix stamped in Unix
time, finite extreme values, floods, long silences and a diverging filter. It never raises,
never publishes a non-finite value, bounds its work per input and counts what it rejects."""

from __future__ import annotations

import logging
import math
import time

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from common.config.estimator import EstimatorConfig
from common.guard import MAX_ITEMS
from common.messages import (
    Detection,
    Message,
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    StateEstimate,
    decode,
    encode,
)
from common.runtime.model.core import Delivery
from services.estimator import EstimatorCore
from services.estimator.core import DETECTION_BUDGET, FIX_BUDGET, MAX_PREDICT_S
from services.estimator.replay import ReplayBuffer

START = (5.0, 20.0, 0.0)
# Far more than one step ever needs (a step is ~1 ms, a full flood budget ~50 ms), far less
# than the hours a Unix-stamped fix used to cost.
STEP_BOUND_S = 2.0


def _fix(stamp: float, seq: int = 1, **kw: float) -> NavFix:
    f = {"x": 5.0 + stamp, "y": 20.0, "heading": 0.0, "speed": 1.0, "std_xy": 0.5}
    f.update(kw)
    return NavFix(
        stamp=stamp,
        seq=seq,
        source="sensor",
        x=f["x"],
        y=f["y"],
        heading=f["heading"],
        speed=f["speed"],
        std_xy=f["std_xy"],
        std_heading=f.get("std_heading", 0.05),
        std_speed=f.get("std_speed", 0.1),
    )


def _scan(stamp: float, seq: int, ids: range, x: float = 30.0) -> ObstacleDetections:
    dets = tuple(
        Detection(id=i, x=x + 0.01 * i, y=20.0, radius=1.0, std_xy=0.3, std_radius=0.1) for i in ids
    )
    return ObstacleDetections(stamp=stamp, seq=seq, source="sensor", detections=dets)


def _deliver(core: EstimatorCore, msg: Message, t: float) -> float:
    """Deliver one message; the wall time it took."""
    stream = "nav" if isinstance(msg, NavFix) else "obstacles"
    t0 = time.perf_counter()
    assert core.deliver(Delivery(source="sensor", stream=stream, msg=msg, t=t)) == []
    return time.perf_counter() - t0


def _step(core: EstimatorCore, t: float) -> tuple[StateEstimate, ObstacleTracks, float]:
    """One step; its outputs after a trip over the wire (which refuses non-finite numbers)."""
    t0 = time.perf_counter()
    out = core.step(t)
    took = time.perf_counter() - t0
    state, tracks = (decode(encode(e.msg, source="estimator", seq=1, sent=t)) for e in out)
    assert isinstance(state, StateEstimate) and isinstance(tracks, ObstacleTracks)
    return state, tracks, took


def _warm(core: EstimatorCore, until: float = 2.0) -> None:
    for k in range(round(until * 10) + 1):
        t = k / 10
        _deliver(core, _fix(t, seq=k + 1), t)
        _step(core, t)


def test_a_fix_stamped_in_unix_time_is_rejected_at_once() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    _warm(core)
    took = _deliver(core, _fix(1.79e9, seq=999), 2.05)
    state, _, step_s = _step(core, 2.1)
    assert took + step_s < STEP_BOUND_S  # it used to predict 1.8e10 sub-steps (hours)
    assert core.inputs_rejected == {"nav.future": 1}
    assert core.nav.fused == 21  # the warm-up fixes only
    assert abs(state.x - (5.0 + 2.1)) < 1.0  # the estimate is still the vehicle's


@pytest.mark.parametrize(
    ("fields", "reason"),
    [
        ({"x": 1e300}, "out_of_range"),
        ({"std_xy": 1e160}, "out_of_range"),
        ({"x": 1e300, "std_xy": 1e160}, "out_of_range"),
        ({"speed": -1e200}, "out_of_range"),
        ({"heading": 1e300, "std_heading": 1e300}, "out_of_range"),
    ],
)
def test_finite_extreme_values_are_rejected_and_counted(
    fields: dict[str, float], reason: str
) -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    _warm(core)
    _deliver(core, _fix(2.05, seq=999, **fields), 2.05)
    state, _, _ = _step(core, 2.1)
    assert core.inputs_rejected == {f"nav.{reason}": 1}
    assert math.hypot(state.x - 7.1, state.y - 20.0) < 1.0


def test_obstacle_scans_are_judged_too() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    _deliver(core, _scan(0.1, 1, range(MAX_ITEMS + 1)), 0.1)  # more than a message may carry
    _deliver(core, _scan(0.2, 2, range(1), x=-1e300), 0.2)
    _deliver(core, _scan(1e9, 3, range(1)), 0.3)
    _deliver(core, _scan(-1e9, 4, range(1)), 0.3)
    _, tracks, _ = _step(core, 0.3)
    assert tracks.tracks == ()
    assert core.inputs_rejected == {
        "obstacles.too_large": 1,
        "obstacles.out_of_range": 1,
        "obstacles.future": 1,
        "obstacles.stale": 1,
    }


def test_rejections_are_logged_once_per_reason_per_mission_second(
    caplog: pytest.LogCaptureFixture,
) -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    with caplog.at_level(logging.WARNING, logger="tidelink.estimator"):
        for k in range(3000):  # 3 mission seconds of a 1 kHz flood of Unix-stamped fixes
            _deliver(core, _fix(1.79e9, seq=k + 1), k / 1000)
    lines = [r.getMessage() for r in caplog.records]
    assert len(lines) == 3, lines
    assert core.inputs_rejected == {"nav.future": 3000}
    assert "rejected a nav message (future)" in lines[0]
    assert "not logged since the last report" in lines[1]


def test_a_flood_inside_the_window_is_cut_at_the_step_budget() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    _warm(core)
    rng = np.random.default_rng(3)
    # plausible fixes in random stamp order: each one would replay every later one
    stamps = 1.0 + rng.random(5000)
    t0 = time.perf_counter()
    for k, s in enumerate(stamps):
        _deliver(core, _fix(float(s), seq=10_000 + k), 2.05)
    _, _, step_s = _step(core, 2.1)
    assert time.perf_counter() - t0 < 10 * STEP_BOUND_S  # was minutes (a replay per fix)
    rejected = core.inputs_rejected
    assert rejected["nav.over_budget"] > 4000
    fused = core.nav.fused - 21
    assert 0 < fused <= FIX_BUDGET
    # the next step has its budget again
    _deliver(core, _fix(2.15, seq=99_999), 2.15)
    assert core.nav.fused - 21 == fused + 1


def test_scan_work_per_step_is_bounded_by_detections() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    per_scan = 16
    for k in range(20):  # 320 detections offered between two steps
        _deliver(core, _scan(0.01 * k, k + 1, range(per_scan)), 0.2)
    assert core.scans.fused == DETECTION_BUDGET // per_scan
    assert core.inputs_rejected["obstacles.over_budget"] == 20 - DETECTION_BUDGET // per_scan


def test_new_ids_beyond_the_track_limit_are_refused() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    for k in range(4):  # 4 x 32 distinct ids within the track timeout
        _step(core, 0.1 * k)
        _deliver(core, _scan(0.1 * k, k + 1, range(32 * k, 32 * (k + 1))), 0.1 * k)
    _, tracks, _ = _step(core, 0.4)
    assert len(tracks.tracks) == MAX_ITEMS
    assert core.inputs_rejected["obstacles.track_limit"] == 4 * 32 - MAX_ITEMS


def test_a_fix_after_a_long_silence_restarts_the_filter_from_itself() -> None:
    core = EstimatorCore(EstimatorConfig(), START)
    _warm(core)
    t = 2.0 + MAX_PREDICT_S + 40.0
    state, _, took = _step(core, t)  # 100 s dead-reckoned: predicted MAX_PREDICT_S at most
    assert took < STEP_BOUND_S and math.isfinite(state.x)
    _deliver(core, _fix(t, seq=500, x=60.0, y=30.0, speed=0.5), t)
    state, _, _ = _step(core, t)
    assert core.resets == {"vehicle_filter": 1, "tracks": 0}
    assert (state.x, state.y, state.v) == pytest.approx((60.0, 30.0, 0.5))
    cov = np.array(state.covariance).reshape(5, 5)
    assert cov[0, 0] == pytest.approx(0.25)  # the fix's own variance, nothing older


def test_an_estimator_started_mid_mission_takes_its_first_fix_not_the_start_pose() -> None:
    # a restarted estimator: the vehicle is 30 m from the configured start when it hears it
    core = EstimatorCore(EstimatorConfig(), START)
    _deliver(core, _fix(27.0, x=35.0, y=24.0, heading=1.0), 27.0)
    state, _, _ = _step(core, 27.0)
    assert (state.x, state.y, state.theta) == pytest.approx((35.0, 24.0, 1.0))
    assert core.resets == {"vehicle_filter": 1, "tracks": 0}
    # a first fix the start pose explains (the mission's first) is fused with it, as before
    core = EstimatorCore(EstimatorConfig(), START)
    _deliver(core, _fix(0.1, x=5.4, y=20.3), 0.1)
    state, _, _ = _step(core, 0.1)
    assert core.resets == {"vehicle_filter": 0, "tracks": 0}
    assert 5.0 < state.x < 5.4 and 20.0 < state.y < 20.3


@pytest.mark.filterwarnings("ignore::scipy.linalg.LinAlgWarning")  # the point of the test
def test_a_diverging_filter_is_reset_and_its_outputs_stay_finite() -> None:
    # a process noise so large that one prediction explodes the covariance
    core = EstimatorCore(EstimatorConfig(accel_psd_m2_s3=1e300), START)
    for k in range(10):
        t = k / 10
        _deliver(core, _fix(t, seq=k + 1), t)
        state, _, _ = _step(core, t + 0.05)
        assert math.hypot(state.x - (5.0 + t), state.y - 20.0) < 1.0
    assert core.resets["vehicle_filter"] == 9  # every fix after the first


finite = st.floats(allow_nan=False, allow_infinity=False)
big = st.floats(0.0, allow_infinity=False)  # non-negative, up to 1.8e308
stamps = st.one_of(st.floats(-10.0, 30.0), finite)
nav_fixes = st.builds(
    NavFix,
    stamp=stamps,
    seq=st.integers(0, 2**40),
    x=st.one_of(st.floats(-50.0, 150.0), finite),
    y=st.one_of(st.floats(-50.0, 90.0), finite),
    heading=finite,
    speed=st.one_of(st.floats(-5.0, 5.0), finite),
    std_xy=st.one_of(st.floats(0.0, 10.0), big),
    std_heading=st.one_of(st.floats(0.0, 1.0), big),
    std_speed=st.one_of(st.floats(0.0, 1.0), big),
)
detections = st.builds(
    Detection,
    id=st.integers(0, 2**31),
    x=st.one_of(st.floats(-50.0, 150.0), finite),
    y=st.one_of(st.floats(-50.0, 90.0), finite),
    radius=st.one_of(st.floats(0.0, 10.0), big),
    std_xy=st.one_of(st.floats(0.0, 2.0), big),
    std_radius=st.one_of(st.floats(0.0, 2.0), big),
)
scans = st.builds(
    ObstacleDetections,
    stamp=stamps,
    seq=st.integers(0, 2**40),
    detections=st.lists(detections, max_size=8).map(tuple),
)


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    script=st.lists(
        st.tuples(st.one_of(nav_fixes, scans), st.floats(0.0, 0.5)), min_size=1, max_size=30
    ),
    ukf=st.booleans(),
)
def test_no_input_makes_the_estimator_raise_hang_or_publish_non_finite_values(
    script: list[tuple[NavFix | ObstacleDetections, float]], ukf: bool
) -> None:
    cfg = EstimatorConfig(vehicle_filter="ukf" if ukf else "ekf", prefilter="mean+lag")
    core = EstimatorCore(cfg, START)
    t = 0.0
    for msg, dt in script:
        t += dt
        assert _deliver(core, msg, t) < STEP_BOUND_S
        _, _, took = _step(core, t)  # the wire round trip checks finiteness
        assert took < STEP_BOUND_S
    assert all(n > 0 for n in core.inputs_rejected.values())


# finite entries whose sum overflows too (1.7e308: health.py sums the entries first)
entries = st.one_of(
    st.floats(-2e12, 2e12),
    st.sampled_from([math.nan, math.inf, -math.inf, 1e12, -0.0, 1.7e308, -1.7e308]),
)


@settings(max_examples=100, deadline=None)
@given(
    n=st.integers(1, 9),
    values=st.lists(entries, min_size=90, max_size=90),
    sparse=st.booleans(),
)
def test_healthy_is_its_numpy_definition(n: int, values: list[float], sparse: bool) -> None:
    # health.py checks on Python floats what these numpy reductions say: every entry finite,
    # every variance in [0, MAX_VARIANCE]
    from services.estimator.health import MAX_VARIANCE, healthy, healthy_entries

    a = np.array(values[: n + n * n])
    if sparse:  # mostly healthy beliefs, one bad entry at most
        tame = np.abs(np.nan_to_num(a, nan=1.0, posinf=1.0, neginf=1.0)) % 10.0
        a = np.where(np.isfinite(a) & (np.arange(a.size) != a.size // 2), tame, a)
    x, P = a[:n], a[n:].reshape(n, n)
    d = np.diagonal(P)
    want = bool(
        np.isfinite(x).all()
        and np.isfinite(P).all()
        and (d >= 0.0).all()
        and (d <= MAX_VARIANCE).all()
    )
    assert healthy(x, P) is want
    assert healthy(x, P.T) is want  # not contiguous
    # on Python floats, P's rows and columns permuted alike (tracks.py: the wire's order)
    back = np.arange(n)[::-1]
    assert healthy_entries(x.tolist(), P[np.ix_(back, back)].ravel().tolist()) is want


def test_healthy_when_the_sum_of_finite_entries_overflows() -> None:
    from services.estimator.health import healthy

    big = np.full(3, 1.7e308)  # finite, their sum is not
    P = np.eye(3)
    assert healthy(big, P)
    assert healthy(np.zeros(3), np.where(P > 0.0, 1.0, 1.7e308))  # the off-diagonal sum
    assert not healthy(np.array([1.7e308, 1.7e308, math.nan]), P)


def test_the_replay_buffer_keeps_at_most_max_entries() -> None:
    buf: ReplayBuffer[int, int] = ReplayBuffer(0, lambda s, m: s + m, 100.0, max_entries=4)
    for k in range(10):
        assert buf.add(1, float(k), k)
    assert len(buf) == 4 and buf.state == 10
    # 4.5 belongs before 5.0, which was dropped: it can no longer be fused in order
    assert buf.cost(1, 4.5, 0) == 0
    assert not buf.add(1, 4.5, 0) and buf.rejected_old == 1
    # 5.5 comes after every dropped entry: fused by replaying the 4 kept ones
    assert buf.cost(1, 5.5, 0) == 5
    assert buf.add(1, 5.5, 0) and buf.state == 11 and len(buf) == 4
