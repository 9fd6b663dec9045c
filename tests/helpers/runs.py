"""Inproc runs shared by the tests of one test process: several compare against the same run.

The default mission is the reference of a handful of tests (lockstep, monitors, placement,
defences); it is run once per process, keyed by the scenario's full repr (every field of it,
seed included), and each test still runs whatever it compares against it.
"""

from __future__ import annotations

from common.config.scenario import Scenario
from common.runtime.model.inproc import run_inproc
from common.runtime.model.result import RunResult

_RUNS: dict[str, RunResult] = {}


def inproc(scenario: Scenario) -> RunResult:
    """run_inproc(scenario), once per distinct scenario in this process (treat it as read-only)."""
    key = repr(scenario)
    if key not in _RUNS:
        _RUNS[key] = run_inproc(scenario)
    return _RUNS[key]
