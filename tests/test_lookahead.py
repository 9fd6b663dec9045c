"""Lockstep look-ahead: which services may start a tick before the last one is complete, and
that doing so changes nothing (lockstep still equals inproc) while it really happens."""

from __future__ import annotations

import logging
import re
from pathlib import Path
from typing import Any

import pytest
from helpers.launch_proc import REPO

from common.config.scenario import load_scenario
from common.runtime.distributed.lockstep import run_lockstep
from common.runtime.distributed.lookahead import Lookahead
from common.runtime.model.inproc import run_inproc
from common.runtime.model.mission import load_mission
from common.runtime.model.record import Record

DEFAULT = REPO / "configs" / "default.toml"
SHORT = REPO / "configs" / "experiments" / "scenarios" / "short.toml"


def _default() -> Lookahead:
    return Lookahead.of(load_mission(load_scenario(DEFAULT)[0]))


def test_the_vehicle_is_never_predictable_the_mission_ends_on_its_truth() -> None:
    la = _default()
    assert la.ending == {"vehicle"}
    assert set(la.period_us) == {"sensor", "estimator", "planner"}
    assert la.period_us["planner"] == 100_000
    assert la.predictable(["planner"]) and not la.predictable(["planner", "vehicle"])


def test_the_sensor_and_estimator_start_while_the_planner_steps_the_vehicle_waits() -> None:
    la = _default()
    # the planner feeds the vehicle alone (its commands); the estimator feeds the planner
    assert la.waits(["estimator", "sensor", "vehicle"], ["planner"]) == {
        "estimator": (),
        "sensor": (),
        "vehicle": ("planner",),
    }
    assert la.waits(["planner", "vehicle"], ["estimator"]) == {
        "planner": ("estimator",),
        "vehicle": (),
    }
    # a service still running the last tick is sent the next one at once (it waits in its
    # inbox), unless another running one feeds it
    assert la.waits(["planner", "vehicle"], ["planner"]) == {"planner": (), "vehicle": ("planner",)}
    assert la.waits(["planner", "sensor"], ["estimator", "planner"]) == {
        "planner": ("estimator",),
        "sensor": (),
    }


def test_wake_inputs_make_a_service_unpredictable(testloop_toml: Path) -> None:
    periodic = Lookahead.of(load_mission(load_scenario(testloop_toml)[0]))
    s, _ = load_scenario(testloop_toml, overrides=["run.mission_params.event_driven=true"])
    evented = Lookahead.of(load_mission(s))
    assert periodic.period_us  # the toy loop's end depends on nothing
    assert len(evented.period_us) < len(periodic.period_us)


class _Silent:
    """A mission that does not say which streams its end depends on."""

    def __init__(self, inner: Any) -> None:
        self.dataflow = inner.dataflow
        self.max_time_s = inner.max_time_s

    def observe(self, record: Record) -> str | None:
        return None


def test_a_mission_that_does_not_say_what_ends_it_gets_no_look_ahead() -> None:
    la = Lookahead.of(_Silent(load_mission(load_scenario(DEFAULT)[0])))  # type: ignore[arg-type]
    assert la.period_us == {} and la.ending == {"estimator", "planner", "sensor", "vehicle"}
    assert not la.predictable(["planner"])


@pytest.mark.deterministic
@pytest.mark.slow
def test_ticks_start_early_in_a_lockstep_run_and_it_still_equals_inproc(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    s, raw = load_scenario(DEFAULT, ["run.max_time_s=20"], seed=4)
    ref = run_inproc(s)
    with caplog.at_level(logging.INFO, logger="tidelink.lockstep"):
        got = run_lockstep(s, raw, tmp_path / "logs")
    ended = [r.getMessage() for r in caplog.records if "lockstep run ended" in r.getMessage()]
    match = re.search(r"after (\d+) ticks \((\d+) started early\)", ended[-1])
    assert match is not None
    ticks, early = int(match[1]), int(match[2])
    # every other tick is the vehicle's and the planner's: the next one starts early
    assert early >= ticks // 3
    assert got.metrics == ref.metrics
    assert (got.reason, got.t_end, got.ticks) == (ref.reason, ref.t_end, ref.ticks)
    assert got.record.keys() == ref.record.keys()
    for key in ref.record.keys():
        assert got.record.stream(*key) == ref.record.stream(*key)
