"""Smoke test of scripts/bench_monitor.py: a short self-test loop launch with one monitor that
leaves by itself, and one that joined and was SIGSTOPped (killed at the end)."""

from __future__ import annotations

from pathlib import Path
from types import ModuleType

import pytest

from tests.helpers.scripts import load_script

# a real launch on the wall clock, beside the other shared realtime tests: it asserts that the
# script measures, never how fast (what the machine's load could change is the benchmark's)
pytestmark = [pytest.mark.slow]


def _bench() -> ModuleType:
    return load_script("bench_monitor")


def test_bench_monitor_measures_the_loop_with_a_monitor(tmp_path: Path) -> None:
    # its case with a SIGSTOPped monitor (monitors that leave by themselves at the end are
    # the live run's, tests/test_live_run.py)
    bench = _bench()
    case = bench.Case("one", 1, stopped=True)
    run = bench.run_case(bench.loop_scenario(4.0, tmp_path), [], case, "plant/status")
    # a smoke test of the script: it measures; how fast is for the benchmark to say
    assert len(run.ages_s) >= 20 and all(a >= 0.0 for a in run.ages_s)
    assert run.metrics.facts.end_reason == "max_time"
    assert run.joined == 1 and run.codes == [None]  # it joined, and was still stopped
