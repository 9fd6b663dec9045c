"""Smoke test of scripts/bench_profile.py on the small scenario's first seconds."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.helpers.scripts import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.background
def test_bench_profile_accounts_for_a_tick(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    bench = load_script("bench_profile")
    small = tmp_path / "small5.toml"
    base = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"
    small.write_text(f'extends = "{base}"\n[run]\nmax_time_s = 5.0\n')
    got = bench.measure(1, small)
    phases = got["phases"]
    # every core's step is timed, and no phase takes more than the whole run
    assert {"planner step", "estimator step", "vehicle step", "sensor step"} <= set(phases)
    assert 0.0 < sum(v for k, v in phases.items() if k != "sequences") <= got["total_s"] * 1.01
    assert got["ticks"] > 0 and len(got["top"]) > 0
    bench.table({"this checkout": dict(got, seed=1)})
    out = capsys.readouterr().out
    assert "whole run" in out and "(the same)" in out
