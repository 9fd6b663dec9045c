"""A sweep in the lockstep runtime (real processes over Zenoh) matches the inproc sweep."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import pytest

from services.experiments.sweep.run import SweepOptions, run_sweep
from services.experiments.sweep.schema import load_experiment

pytestmark = [pytest.mark.slow, pytest.mark.deterministic, pytest.mark.heavy]

ROOT = Path(__file__).resolve().parents[1]
SMOKE = ROOT / "configs" / "experiments" / "smoke.toml"


def test_lockstep_sweep_writes_outputs_and_equals_inproc(tmp_path: Path) -> None:
    exp = load_experiment(SMOKE)
    axis = dataclasses.replace(exp.axes[0], values=exp.axes[0].values[::2])  # ideal, loss20
    small = dataclasses.replace(exp, controllers=("fuzzy_pid",), seeds=1, axes=(axis,))
    ls = run_sweep(
        small,
        "smoke-lockstep",
        SweepOptions(out=tmp_path / "ls", runtime="lockstep", jobs=2, rich=False),
    )
    ip = run_sweep(
        small,
        "smoke-inproc",
        SweepOptions(out=tmp_path / "ip", runtime="inproc", jobs=1, rich=False, plots=False),
    )
    assert (ls.total, ls.errors, ip.errors) == (2, 0, 0)
    with (tmp_path / "ls" / "results.csv").open() as fh:
        rows = list(csv.DictReader(fh))
    assert {r["runtime"] for r in rows} == {"lockstep"} and len(rows) == 2
    assert (tmp_path / "ls" / "summary.md").exists()
    assert (tmp_path / "ls" / "plots" / "travel_time_s.png").exists()
    for r in rows:  # every service logged in its own process, under the run's folder
        logs = tmp_path / "ls" / "runs" / r["run_id"] / "logs"
        assert {p.stem for p in logs.glob("*.log")} == {"estimator", "planner", "sensor", "vehicle"}
    # the two runtimes are bit-identical, so the same run ids carry the same trajectories
    want = {r["run_id"]: r["trajectory_sha256"] for r in ip.rows}
    assert {r["run_id"]: r["trajectory_sha256"] for r in rows} == want
