"""The onboard tracker acknowledges the path it follows; the planner predicts it along that path.

services/tracker/core.py (PathAck on every path message received) and
services/planner/shadow.py (the tracker's closed loop rolled out on the path acknowledged).
"""

from __future__ import annotations

import bisect
import logging
import math
from pathlib import Path

import msgspec
import numpy as np
import pytest
from helpers.samples import one_of_each

from common.config.scenario import Scenario, load_scenario
from common.messages import PathAck, PathMsg, StateEstimate, TruthState
from common.runtime.model.core import Delivery
from common.runtime.model.inproc import run_inproc
from common.world.check import check_scenario
from services.control.command.link import Prediction
from services.control.loop import CommandLoop
from services.planner.geometry.nurbs_curve import NurbsCurve, clamped_uniform_knots
from services.planner.geometry.planned_path import PlannedPath
from services.planner.shadow import TrackerShadow
from services.planner.shaping.path_arc_reference import PathArcReference
from services.tracker.core import TrackerCore

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
LOG = logging.getLogger("test")


def _load(*sets: str) -> Scenario:
    s, _ = load_scenario(DEFAULT, [*sets, 'runtime.kind="inproc"'], check=check_scenario)
    return s


def _loop(s: Scenario) -> CommandLoop[PathArcReference]:
    return CommandLoop(s.planner, s.controller, s.vehicle, s.world, LOG)


def _path_msg(path_id: int, stamp: float) -> PathMsg:
    sample = next(m for m in one_of_each() if isinstance(m, PathMsg))
    return msgspec.structs.replace(sample, path_id=path_id, stamp=stamp)


def _estimate(t: float, x: float, y: float, theta: float = 0.0, v: float = 1.5) -> StateEstimate:
    return StateEstimate(
        stamp=t, x=x, y=y, theta=theta, v=v, w=0.0, covariance=tuple(np.eye(5).ravel() * 0.01)
    )


def _line(y: float, x0: float = 0.0, x1: float = 60.0) -> PathArcReference:
    """A straight path along y from x0 to x1 at 1.5 m/s."""
    ctrl = np.array([[x0 + (x1 - x0) * k / 4, y] for k in range(5)])
    curve = NurbsCurve(3, ctrl, np.ones(5), clamped_uniform_knots(5, 3))
    return PathArcReference(PlannedPath(curve), 1.5)


def test_every_path_message_is_acknowledged_with_the_path_followed_and_since_when() -> None:
    tracker = TrackerCore(_loop(_load('controller.placement="onboard"')))
    assert tracker.step(0.0) == []  # nothing received, nothing to say
    tracker.deliver(Delivery(source="planner", stream="path", msg=_path_msg(2, 1.0), t=1.5))
    (ack,) = [e.msg for e in tracker.step(1.55) if e.stream == "ack"]
    assert isinstance(ack, PathAck) and (ack.path_id, ack.since, ack.stamp) == (2, 1.5, 1.55)
    assert [e for e in tracker.step(1.6) if e.stream == "ack"] == []  # once per message
    # a repeat of it, and an older path late: acknowledged with the path followed, unchanged
    for msg in (_path_msg(2, 3.0), _path_msg(1, 0.5)):
        tracker.deliver(Delivery(source="planner", stream="path", msg=msg, t=3.5))
        (again,) = [e.msg for e in tracker.step(3.55) if e.stream == "ack"]
        assert isinstance(again, PathAck) and (again.path_id, again.since) == (2, 1.5)


def test_a_path_from_the_future_is_rejected_and_not_acknowledged() -> None:
    tracker = TrackerCore(_loop(_load('controller.placement="onboard"')))
    future = _path_msg(1, 500.0)
    tracker.deliver(Delivery(source="planner", stream="path", msg=future, t=1.0))
    assert [e for e in tracker.step(1.05) if e.stream == "ack"] == []
    assert tracker.loop.path_id == 0 and sum(tracker.inputs_rejected.values()) == 1


def _ack(loop: CommandLoop[PathArcReference], t: float, path_id: int, since: float) -> None:
    loop.inputs.offer(t, PathAck(stamp=t, path_id=path_id, since=since))


def test_an_acknowledgement_from_the_future_is_rejected_and_an_older_one_kept_out() -> None:
    loop = _loop(_load())
    shadow = TrackerShadow(loop)
    shadow.put(1, _line(20.0), expected_t=100.0)
    shadow.put(2, _line(21.0), expected_t=100.0)
    _ack(loop, 4.0, 1, since=3.0)
    # a forged stamp would hold the place of every later acknowledgement: counted, not taken
    loop.inputs.offer(4.5, PathAck(stamp=400.0, path_id=2, since=3.5))
    assert loop.inputs.rejected == {"ack.future": 1}
    loop.inputs.offer(5.0, PathAck(stamp=3.9, path_id=2, since=3.5))  # late, behind the newest
    shadow.predict(5.0, _estimate(4.5, 10.0, 20.0), 6.0)
    assert shadow.followed_at(4.0) == 1  # neither taken: path 2 not before its expected 100 s


def test_the_path_followed_is_the_acknowledged_one_a_newer_one_from_when_it_is_expected() -> None:
    loop = _loop(_load())
    shadow = TrackerShadow(loop)
    assert shadow.followed_at(10.0) == 0  # nothing sent: the tracker stops
    shadow.put(1, _line(20.0), expected_t=2.0)
    assert (shadow.followed_at(1.9), shadow.followed_at(2.0)) == (0, 1)
    _ack(loop, 4.0, 1, since=3.0)  # it got there later than expected
    shadow.predict(5.0, _estimate(4.5, 10.0, 20.0), 6.0)  # takes in the acknowledgement
    assert (shadow.followed_at(2.5), shadow.followed_at(3.0)) == (0, 1)
    shadow.put(2, None, expected_t=7.0)  # a NO_PATH, not yet acknowledged
    assert (shadow.followed_at(6.9), shadow.followed_at(7.0)) == (1, 2)


def test_the_rollout_follows_the_path_in_closed_loop_and_stops_without_one() -> None:
    s = _load()
    loop = _loop(s)
    shadow = TrackerShadow(loop)
    est = _estimate(10.0, 5.0, 21.0)  # 1 m left of the path, under way along it
    # no path acknowledged nor expected: the tracker stops; in still water, within 5 m
    stopped = shadow.predict(10.0, est, 20.0).at_effect
    assert math.hypot(stopped[0] - 5.0, stopped[1] - 21.0) < 5.0 and stopped[3] < 0.1
    shadow.put(1, _line(20.0), expected_t=0.0)
    pred = shadow.predict(10.0, est, 20.0)
    x, y, theta, v, _ = pred.at_effect
    assert x == pytest.approx(5.0 + 10 * 1.5, abs=2.0)  # ~cruise speed along it ...
    assert abs(y - 20.0) < 0.3 and abs(theta) < 0.1  # ... back on it, as the tracker steers
    assert pred.now == pytest.approx((5.0, 21.0, 0.0, 1.5, 0.0))  # the estimate is now


def test_the_onboard_planner_predicts_the_vehicle_it_does_not_command() -> None:
    # the planner on a ship across a 1 s link, the tracker onboard, in a cross-current: where
    # the planner expects the vehicle when a path sent now gets there (the tracker's loop
    # rolled out from 1 s old estimates, 2 s ahead), where a plan made now starts, is
    # compared with where it is then, at every step of the run
    s = _load(
        'placement.stations=[{name="ship", x_m=50.0, y_m=-20.0, medium="generic"}]',
        'placement.services={planner="ship"}',
        'controller.placement="onboard"',
        'network.default={delay_s=1.0, jitter="normal", jitter_s=0.02}',
        "network.links=[]",
        "world.current.speed_mps=0.2",
        "world.current.direction_deg=90.0",
        "run.max_time_s=60.0",
    )
    expected: list[tuple[float, tuple[float, float]]] = []
    predict = TrackerShadow.predict

    def noting(shadow: TrackerShadow, t: float, est: StateEstimate, effect_t: float) -> Prediction:
        pred = predict(shadow, t, est, effect_t)
        expected.append((pred.effect_t, (pred.at_effect[0], pred.at_effect[1])))
        return pred

    mp = pytest.MonkeyPatch()
    mp.setattr(TrackerShadow, "predict", noting)
    try:
        got = run_inproc(s)
    finally:
        mp.undo()
    truths = [m for m in got.record.stream("vehicle", "truth") if isinstance(m, TruthState)]
    truth = [(m.stamp, (m.x, m.y)) for m in truths]
    times = [t for t, _ in truth]
    errs = []
    for t, xy in expected:
        i = min(bisect.bisect_left(times, t), len(times) - 1)
        if abs(times[i] - t) < 0.03:  # the vehicle's step
            errs.append(math.dist(xy, truth[i][1]))
    assert len(errs) > 500
    rms = math.sqrt(sum(e * e for e in errs) / len(errs))
    assert rms < 0.5, rms  # predicted under no commands, as before the shadow: 0.91 m
