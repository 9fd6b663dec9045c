"""Input plausibility (issue 14): the shared judge and rate-limited log, and the gates at the
entry of the sensor and planner cores (the estimator's are in test_estimator_defence.py)."""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pytest
from helpers.planner_world import planner_core
from hypothesis import given
from hypothesis import strategies as st

from common.config.scenario import load_scenario
from common.config.sensor import SensorConfig
from common.config.world import AreaConfig, WorldConfig
from common.guard import MAX_ITEMS, Plausibility, RateLimitedLog
from common.messages import ObstacleTracks, StateEstimate, Track, TruthState
from common.runtime.model.core import Delivery
from common.world import World
from services.planner.core import PlannerCore
from services.sensor import SensorCore

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
JUDGE = Plausibility.of_area(AreaConfig())  # 100 m x 40 m: positions in [-100, 200] x [-100, 140]


def test_stamps_are_judged_against_the_receivers_time() -> None:
    assert JUDGE.stamp(10.0, 10.0) is None
    assert JUDGE.stamp(10.9, 10.0) is None  # within the clock-skew tolerance
    assert JUDGE.stamp(1.79e9, 10.0) == "future"  # Unix time
    assert JUDGE.stamp(-1e9, 10.0) == "stale"
    assert JUDGE.stamp(math.nan, 10.0) == "non_finite"


def test_magnitudes_are_judged_against_the_world() -> None:
    assert JUDGE.position(-99.0, 139.0) is None
    assert JUDGE.position(201.0, 20.0) == "out_of_range"
    assert JUDGE.position(1e300, 20.0) == "out_of_range"
    assert JUDGE.position(math.inf, 20.0) == "non_finite"
    assert JUDGE.length(0.0, 100.0) is None and JUDGE.length(1e160) == "out_of_range"
    assert JUDGE.length(-0.1) == "out_of_range"
    assert JUDGE.angle_std(math.pi) is None and JUDGE.angle_std(4.0) == "out_of_range"
    assert JUDGE.speed(-2.0, 2.0) is None and JUDGE.speed(1e3) == "out_of_range"
    assert JUDGE.angle(1e300) is None  # any finite angle: wrapped where it is used
    assert JUDGE.items(MAX_ITEMS) is None and JUDGE.items(MAX_ITEMS + 1) == "too_large"


@given(t=st.lists(st.floats(0.0, 10.0), min_size=1, max_size=200).map(sorted))
def test_the_rate_limited_log_writes_at_most_one_line_per_reason_per_second(
    t: list[float],
) -> None:
    lines: list[str] = []

    class Capture(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            lines.append(record.getMessage())

    logger = logging.getLogger("tidelink.test.ratelog")
    logger.propagate = False
    handler = Capture()
    logger.addHandler(handler)
    try:
        rl = RateLimitedLog(logger)
        at = [i for i, x in enumerate(t) if rl.warn("bad", x, "t=%.3f", x)]
    finally:
        logger.removeHandler(handler)
    assert rl.counts == {"bad": len(t)}
    assert at[0] == 0 and len(lines) == len(at)
    logged = [t[i] for i in at]
    assert all(b - a >= 1.0 for a, b in zip(logged, logged[1:], strict=False))
    assert len(at) <= math.floor(t[-1] - t[0]) + 1
    # each line tells the count so far and how many went unlogged since the previous one
    for j, i in enumerate(at):
        gap = i - at[j - 1] - 1 if j else 0
        more = f", {gap} not logged since the last report" if gap else ""
        assert lines[j] == f"t={t[i]:.3f} [bad: {i + 1} so far{more}]"


# -- the sensor -------------------------------------------------------------------------------


def _truth(stamp: float, x: float = 50.0, **kw: float) -> Delivery:
    msg = TruthState(
        stamp=stamp, x=x, y=kw.get("y", 20.0), theta=0.0, v=kw.get("v", 1.0), w=kw.get("w", 0.0)
    )
    return Delivery(source="vehicle", stream="truth", msg=msg, t=kw.get("t", stamp))


def test_a_future_truth_cannot_lock_the_sensor_out() -> None:
    core = SensorCore(SensorConfig(), World(WorldConfig()), np.random.default_rng(1))
    core.deliver(_truth(1.79e9, t=0.0))  # would be "the newest" forever
    core.deliver(_truth(0.0, x=1e300))
    core.deliver(_truth(0.0, v=-1e200))
    for k in range(1, 11):
        core.deliver(_truth(0.1 * k, x=50.0 + 0.1 * k))
        core.step(0.1 * k)
    assert core.inputs_rejected == {"truth.future": 1, "truth.out_of_range": 2}
    out = core.step(1.1)
    nav = [e.msg for e in out if e.stream == "nav"]
    assert core._truth is not None and core._truth.stamp == pytest.approx(1.0)
    assert not nav or abs(nav[0].x - 51.0) < 5.0


# -- the planner ------------------------------------------------------------------------------

COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))


def _planner() -> PlannerCore:
    s, _ = load_scenario(DEFAULT)
    return planner_core(s)


def _estimate(stamp: float, t: float, x: float = 5.0, v: float = 1.0) -> Delivery:
    est = StateEstimate(stamp=stamp, x=x, y=20.0, theta=0.0, v=v, w=0.0, covariance=COV)
    return Delivery(source="estimator", stream="state", msg=est, t=t)


def _track(oid: int, x: float = 40.0, vx: float = 0.0) -> Track:
    cov = tuple(0.1 if i % 7 == 0 else 0.0 for i in range(36))
    return Track(id=oid, x=x, y=20.0, vx=vx, vy=0.0, ax=0.0, ay=0.0, radius=1.0, covariance=cov)


def test_the_planner_keeps_the_last_plausible_estimate() -> None:
    core = _planner()
    core.deliver(_estimate(0.0, 0.05))
    core.deliver(_estimate(1.79e9, 0.1))  # an estimate that would never grow stale
    core.deliver(_estimate(0.1, 0.15, x=1e300))
    core.deliver(_estimate(0.1, 0.15, v=500.0))
    state = core.inputs.state
    assert state is not None and state.stamp == 0.0 and state.x == 5.0
    assert core.inputs_rejected == {"state.future": 1, "state.out_of_range": 2}
    out = core.step(0.2)
    assert any(e.stream == "cmd" for e in out)


def test_the_planner_refuses_oversized_or_absurd_track_sets() -> None:
    core = _planner()
    many = ObstacleTracks(stamp=0.0, tracks=tuple(_track(100 + i) for i in range(MAX_ITEMS + 1)))
    core.deliver(Delivery(source="estimator", stream="tracks", msg=many, t=0.05))
    fast = ObstacleTracks(stamp=0.0, tracks=(_track(100, vx=1e6),))
    core.deliver(Delivery(source="estimator", stream="tracks", msg=fast, t=0.05))
    assert core.tracks is None
    fine = ObstacleTracks(stamp=0.0, tracks=(_track(100, vx=0.5),))
    core.deliver(Delivery(source="estimator", stream="tracks", msg=fine, t=0.05))
    assert core.tracks == fine
    assert core.inputs_rejected == {"tracks.too_large": 1, "tracks.out_of_range": 1}
