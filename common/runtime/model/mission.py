"""What a runtime runs: a mission declares its dataflow, says when it is over, computes metrics."""

from __future__ import annotations

import importlib
from typing import Any, Protocol

from common.config.scenario import Scenario
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.record import Record
from common.runtime.model.seqwindow import max_seq_gap


class Mission(Protocol):
    """A declared dataflow plus its end condition and metrics (pure; runtime-independent)."""

    dataflow: Dataflow
    max_time_s: float

    def observe(self, record: Record) -> str | None:
        """Called after each tick with everything published so far: an end reason, or None."""

    def metrics(self, record: Record) -> dict[str, Any]: ...


def mission_record(mission: Mission) -> Record:
    """An empty Record for a run of `mission`: its seq window sized to what the mission's
    streams can publish (common/runtime/model/seqwindow.py)."""
    return Record(max_seq_gap(mission.dataflow, mission.max_time_s))


def load_mission(scenario: Scenario) -> Mission:
    """Instantiate the scenario's `[run] mission = "module:Class"`."""
    module_name, _, cls_name = scenario.run.mission.partition(":")
    try:
        cls = getattr(importlib.import_module(module_name), cls_name)
    except (ImportError, AttributeError) as exc:
        raise ValueError(f"run.mission: cannot load {scenario.run.mission!r}: {exc}") from None
    mission: Mission = cls(scenario)
    return mission
