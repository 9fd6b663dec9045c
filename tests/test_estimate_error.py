"""One estimate error (common/estimate_error.py): the truth interpolated at each estimate's
stamp, and metrics.json, the monitor and Foxglove showing the same number for the same run."""

from __future__ import annotations

import json
import math
import random
from pathlib import Path

import numpy as np
import pytest

from common.config.scenario import load_scenario
from common.estimate_error import estimate_errors
from common.messages import StateEstimate, TruthState
from common.runtime.model.record import Record
from common.world import World
from services.foxglove.view import FoxgloveView
from services.mission.metrics import mission_metrics
from services.monitor.state import VehicleView

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
TRUTH_DT = 0.07  # s; not a divisor of the estimates' 0.1 s: most estimates fall between samples
END_S = 3.0
OFF_X, OFF_Y, OFF_THETA = 0.3, 0.4, 0.05  # every estimate's error (m, m, rad)


def _pose(t: float) -> tuple[float, float, float]:
    """x, y (m) and heading (rad, wrapped): the heading turns through the wrap at t = 0.28 s."""
    return 5.0 + 1.5 * t, 20.0 + 0.2 * t, math.remainder(3.0 + 0.5 * t, 2 * math.pi)


def _truth() -> list[TruthState]:
    out = []
    for i in range(int(END_S / TRUTH_DT) + 1):
        t = i * TRUTH_DT
        x, y, theta = _pose(t)
        out.append(
            TruthState(
                stamp=t,
                source="vehicle",
                seq=i + 1,
                x=x,
                y=y,
                theta=theta,
                v=1.5,
                w=0.5,
                current_x=0.1 * t,
            )
        )
    return out


def _estimates(times: list[float]) -> list[StateEstimate]:
    out = []
    for i, t in enumerate(times):
        x, y, theta = _pose(t)
        out.append(
            StateEstimate(
                stamp=t, source="estimator", seq=i + 1, x=x + OFF_X, y=y + OFF_Y,
                theta=math.remainder(theta + OFF_THETA, 2 * math.pi), v=1.5, w=0.5,
                covariance=tuple(np.eye(5).ravel().tolist()), current_x=0.1 * t + 0.03,
            )
        )  # fmt: skip
    return out


ESTIMATE_TIMES = [round(0.1 * k, 10) for k in range(1, 30)]


def test_the_truth_is_interpolated_at_each_stamp_the_heading_across_the_wrap() -> None:
    errors = estimate_errors(_estimates(ESTIMATE_TIMES), _truth())
    assert len(errors.scored) == len(ESTIMATE_TIMES)
    assert errors.error.shape == (len(ESTIMATE_TIMES), 3)
    assert errors.error[:, 0] == pytest.approx(np.full(len(ESTIMATE_TIMES), OFF_X), abs=1e-9)
    assert errors.error[:, 1] == pytest.approx(np.full(len(ESTIMATE_TIMES), OFF_Y), abs=1e-9)
    assert errors.position_m == pytest.approx(np.full(len(ESTIMATE_TIMES), 0.5), abs=1e-9)
    # the estimates at 0.2 s and 0.3 s lie on either side of the wrap: still 0.05 rad off
    assert errors.error[:, 2] == pytest.approx(np.full(len(ESTIMATE_TIMES), OFF_THETA), abs=1e-9)
    assert errors.current_mps == pytest.approx(np.full(len(ESTIMATE_TIMES), 0.03), abs=1e-9)


def test_the_truth_may_come_in_any_order() -> None:
    truth = _truth()
    shuffled = truth[:]
    random.Random(3).shuffle(shuffled)
    est = _estimates(ESTIMATE_TIMES)
    assert np.array_equal(
        estimate_errors(est, shuffled).position_m, estimate_errors(est, truth).position_m
    )


def test_an_estimate_outside_the_truths_span_is_scored_only_within_hold_s() -> None:
    truth = [q for q in _truth() if 1.0 <= q.stamp <= 2.0]
    first, last = truth[0].stamp, truth[-1].stamp
    est = _estimates([first - 0.15, first, 1.5, last, last + 0.15, last + 0.5])
    assert [e.stamp for e in estimate_errors(est, truth).scored] == [first, 1.5, last]
    held = estimate_errors(est, truth, hold_s=0.2)
    assert [e.stamp for e in held.scored] == [first - 0.15, first, 1.5, last, last + 0.15]
    assert estimate_errors(est, []).scored == []
    assert estimate_errors([], truth).position_m.shape == (0,)


def test_metrics_the_monitor_and_foxglove_show_the_same_number() -> None:
    scenario, _ = load_scenario(DEFAULT, ["world.polygons=[]", "world.moving=[]"])
    truth, est = _truth(), _estimates(ESTIMATE_TIMES)
    shared = estimate_errors(est, truth).position_m
    # metrics.json
    record = Record()
    for q in truth:
        record.add("vehicle", "truth", q)
    for e in est:
        record.add("estimator", "state", e)
    metrics = mission_metrics(record, scenario, World(scenario.world))
    assert metrics.estimation_rms_m == float(np.sqrt(np.mean(shared**2)))
    # live, as a watcher gets them: each estimate before the truth samples up to its stamp
    arrivals = sorted(
        [(q.stamp, 1, q) for q in truth] + [(e.stamp, 0, e) for e in est],
        key=lambda a: (a[0], a[1]),
    )
    view, monitor = FoxgloveView(scenario), VehicleView()
    foxglove: list[float] = []
    shown: dict[float, float] = {}  # the monitor's number for each estimate, once truth passed
    for _, is_truth, msg in arrivals:
        source = ("vehicle", "truth") if is_truth else ("estimator", "state")
        frames = view.translate(*source, msg)
        foxglove += [
            json.loads(f.data)["error_m"] for f in frames if f.topic == "/plot/estimate_error"
        ]
        monitor.see(msg)
        if monitor.estimate is not None and monitor.est_error_m is not None:
            shown[monitor.estimate.stamp] = monitor.est_error_m
    assert foxglove == shared.tolist()
    assert [shown[t] for t in ESTIMATE_TIMES] == shared.tolist()
