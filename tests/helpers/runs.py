"""Inproc reference runs shared by the whole test session: several tests compare against one run.

A run is keyed by the scenario's full repr (every field, seed included; but the runtime's kind
and time scale, which an inproc run does not read). Within a process it is kept in memory; across
the pytest-xdist workers of one session it is pickled into the session's cache directory
(TIDELINK_TEST_RUNS, set by tests/conftest.py), computed by whichever worker asks first
while the others wait on its file lock. Treat a result as read-only.
"""

from __future__ import annotations

import dataclasses
import fcntl
import hashlib
import os
import pickle
from pathlib import Path

from common.config.scenario import Scenario
from common.runtime.model.inproc import run_inproc
from common.runtime.model.result import RunResult

CACHE_ENV = "TIDELINK_TEST_RUNS"
_RUNS: dict[str, RunResult] = {}


def inproc(scenario: Scenario) -> RunResult:
    """run_inproc(scenario), once per distinct scenario in this test session."""
    runtime = dataclasses.replace(scenario.runtime, kind="inproc", time_scale=1.0)
    key = repr(dataclasses.replace(scenario, runtime=runtime))
    if key in _RUNS:
        return _RUNS[key]
    directory = os.environ.get(CACHE_ENV)
    if not directory:
        _RUNS[key] = run_inproc(scenario)
        return _RUNS[key]
    path = Path(directory) / hashlib.sha256(key.encode()).hexdigest()
    with open(path.with_suffix(".lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)  # one worker computes, the others wait for it
        if path.exists():
            result: RunResult = pickle.loads(path.read_bytes())
        else:
            result = run_inproc(scenario)
            tmp = path.with_suffix(".tmp")
            tmp.write_bytes(pickle.dumps(result))
            tmp.replace(path)
    _RUNS[key] = result
    return result
