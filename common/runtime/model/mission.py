"""What a runtime runs: a mission declares its dataflow, says when it is over, computes metrics."""

from __future__ import annotations

import importlib
from typing import Protocol

import msgspec

from common.config.errors import ConfigError
from common.config.missions import resolve_mission, unknown_mission
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

    def ends_on(self, service: str, stream: str) -> bool:
        """Does what `observe` returns depend on this stream at all? (A lockstep run judges a
        tick's end before the services publishing none of those streams have finished it,
        common/runtime/distributed/lookahead.py.) When in doubt, True."""

    def metrics(self, record: Record) -> msgspec.Struct:
        """The mission's metrics of a run's record: a struct whose fields are metrics.json's
        keys beside the run's facts (common/runtime/metrics_record.py)."""


def preload(mission: Mission) -> tuple[str, ...]:
    """The modules a service process of `mission` imports (the fork server's preload): the
    mission's own `preload` when it declares one, else the AUV services'."""
    from common.runtime.processes.forkserver import PRELOAD, RUNTIMES

    declared = getattr(mission, "preload", None)
    return PRELOAD if declared is None else (*RUNTIMES, type(mission).__module__, *declared)


def ends_on(mission: Mission, service: str, stream: str) -> bool:
    """mission.ends_on; True for a registered mission that does not say (no look-ahead)."""
    judge = getattr(mission, "ends_on", None)
    return True if judge is None else bool(judge(service, stream))


def mission_record(mission: Mission) -> Record:
    """An empty Record for a run of `mission`: its seq window sized to what the mission's
    streams can publish (common/runtime/model/seqwindow.py)."""
    return Record(max_seq_gap(mission.dataflow, mission.max_time_s))


def load_mission(scenario: Scenario) -> Mission:
    """Instantiate the scenario's `[run] mission`, a registered mission (common.config.missions).

    Only a registered target is ever imported; RunConfig has already refused any other value,
    this checks again for a Scenario built some other way.
    """
    found = resolve_mission(scenario.run.mission)
    if found is None:
        raise ConfigError("", ("run", "mission"), unknown_mission(scenario.run.mission))
    name, target = found
    try:
        module, _, attr = target.partition(":")
        cls = getattr(importlib.import_module(module), attr)
    except (ImportError, AttributeError) as exc:
        raise ValueError(
            f"run.mission: the registered mission {name!r} ({target}) cannot be loaded: {exc}"
        ) from None
    mission: Mission = cls(scenario)
    return mission
