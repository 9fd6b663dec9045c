"""A sweep killed with SIGKILL half way, then rerun, completes only the runs it lacked."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"

# 2 profiles x 2 controllers x 1 seed = 4 runs of the fast baselines, one after another:
# killed after 2, the third running (a killed pool of workers: test_sweep_orphans); the runs
# are the small scenario's first 8 s (small8.toml, written beside the experiment)
EXPERIMENT = """
name = "resume"
scenario = "small8.toml"
seeds = 1
controllers = ["backstepping", "fuzzy_pid"]
[[axes]]
name = "network"
[[axes.values]]
label = "ideal"
set = { "network.default" = {} }
[[axes.values]]
label = "lossy"
set = { "network.default" = { delay_s = 0.1, loss = "bernoulli", loss_p = 0.1 } }
"""
TOTAL = 4
KILL_AFTER = 2


def _sweep(exp: Path, out: Path) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "services.cli",
            "sweep",
            str(exp),
            "--runtime",
            "inproc",
            "--jobs",
            "1",
            "--out",
            str(out),
            "--no-plots",  # what is resumed are the runs; plots are test_sweep_run's
        ],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
    )  # its own process group: the kill takes whatever it started too


def _rows(out: Path) -> list[dict[str, str]]:
    with (out / "results.csv").open() as fh:
        return list(csv.DictReader(fh))


@pytest.mark.heavy
def test_a_killed_sweep_resumes_without_redoing_or_losing_runs(tmp_path: Path) -> None:
    exp = tmp_path / "resume.toml"
    exp.write_text(EXPERIMENT)
    (tmp_path / "small8.toml").write_text(f'extends = "{SMALL}"\n[run]\nmax_time_s = 8.0\n')
    out = tmp_path / "out"
    first = _sweep(exp, out)
    assert first.stderr is not None
    done = 0
    try:
        for line in first.stderr:  # one progress line per run, after its row is on disk
            if line.startswith("["):
                done += 1
                if done == KILL_AFTER:
                    break
    finally:
        os.killpg(first.pid, signal.SIGKILL)
        first.communicate(timeout=60)
    assert first.returncode == -signal.SIGKILL
    before = _rows(out)
    assert KILL_AFTER <= len(before) < TOTAL, "the kill must leave runs to do"

    second = _sweep(exp, out)
    stdout, stderr = second.communicate(timeout=600)
    assert second.returncode == 0, stderr
    assert f"{TOTAL} runs, {len(before)} already done, {TOTAL - len(before)} run now" in stdout
    after = _rows(out)
    ids = [r["run_id"] for r in after]
    assert len(ids) == TOTAL and len(set(ids)) == TOTAL  # each run exactly once
    assert after[: len(before)] == before  # the first rows were kept, not re-run
    assert all(r["status"] == "ok" for r in after)
    assert (out / "summary.md").exists()
