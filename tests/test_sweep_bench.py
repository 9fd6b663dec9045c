"""Smoke test of scripts/bench_sweep.py on the small scenario (inproc only, no plots)."""

from __future__ import annotations

import math
import subprocess
from pathlib import Path

import pytest

from tests.helpers.scripts import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.background
def test_bench_sweep_reports_runs_per_minute(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    bench = load_script("bench_sweep")
    # the small scenario's first 8 s: a smoke test of the script, not of the runs
    small = tmp_path / "small8.toml"
    base = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"
    small.write_text(f'extends = "{base}"\n[run]\nmax_time_s = 8.0\n')
    rpm = bench.main(small, seeds=1, jobs=1, runtimes=["inproc"])
    # a smoke test of the script: it reports a rate; how high is for the benchmark to say
    assert set(rpm) == {"inproc"} and math.isfinite(rpm["inproc"]) and rpm["inproc"] > 0.0
    out = capsys.readouterr().out
    assert "runs/min" in out and ", 0 failed" in out


def test_bench_help_says_how_to_run_it_and_installs_nothing(tmp_path: Path) -> None:
    # from a copy of the script alone: were it to set anything up, it would fail there
    script = tmp_path / "scripts" / "bench"
    script.parent.mkdir()
    script.write_bytes((ROOT / "scripts" / "bench").read_bytes())
    script.chmod(0o755)
    for flag in ("-h", "--help"):
        done = subprocess.run([str(script), flag], capture_output=True, text=True, timeout=30)
        assert done.returncode == 0 and "Run one: scripts/bench" in done.stdout
    assert sorted(p.name for p in tmp_path.iterdir()) == ["scripts"]
