"""Smoke test of scripts/bench_sequence.py and its measurement (services/experiments/
sequence_cost.py): a few control steps at two horizons."""

from __future__ import annotations

import pytest

from services.experiments.netreport.sequence_cost import bench_steps
from tests.helpers.scripts import load_script


def test_bench_sequence_times_steps_and_sizes_commands(capsys: pytest.CaptureFixture[str]) -> None:
    bench = load_script("bench_sequence")
    _, single = bench_steps("nurbs", 0.0, 5)
    times, sizes = bench_steps("nurbs", 2.0, 5)
    assert len(times) == len(sizes) == 5 and min(times) >= 0.0
    # 20 future entries of 1-3 bytes each for v and w on top of the single command
    assert min(sizes) >= max(single) + 2 * 20
    bench.main_steps(3, [0.0, 1.0])
    out = capsys.readouterr().out
    assert "x bytes" in out and "fuzzy_pid" in out
