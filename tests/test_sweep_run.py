"""The smoke sweep inproc (3 profiles x 3 controllers, 2 of its 3 seeds): results.csv,
summary, plots, Dask."""

from __future__ import annotations

import csv
import dataclasses
import math
from pathlib import Path

import pytest

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc
from services.cli import main
from services.experiments.sweep.run import SweepOptions, SweepReport, run_sweep
from services.experiments.sweep.schema import Experiment, load_experiment
from services.experiments.sweep.stats import bootstrap_ci

ROOT = Path(__file__).resolve().parents[1]
# the smoke sweep (a module fixture) and the cluster: whole sweeps, CPU-bound
pytestmark = pytest.mark.background

SMOKE = ROOT / "configs" / "experiments" / "smoke.toml"
SMALL = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"
PLOTS = (
    "success",
    "travel_time_s",
    "xte_optimal_rms_m",
    "min_clearance_m",
    "control_actions_on_path",
)


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> tuple[Experiment, SweepReport]:
    # 2 seeds, not the file's 3, and 2 of its 3 networks (ideal, loss20): the same kinds of
    # rows and intervals (n = 2) at 4/9 of the CPU
    full = load_experiment(SMOKE)
    axis = dataclasses.replace(full.axes[0], values=full.axes[0].values[::2])
    exp = dataclasses.replace(full, seeds=2, axes=(axis,))
    out = tmp_path_factory.mktemp("smoke")
    # one run after another in this process (a pool of workers is test_sweep_lockstep's)
    rep = run_sweep(exp, str(SMOKE), SweepOptions(out=out, runtime="inproc", jobs=1, rich=False))
    return exp, rep


def _csv(path: Path) -> list[dict[str, str]]:
    with path.open() as fh:
        return list(csv.DictReader(fh))


def test_every_run_is_a_row_with_its_grid_parameters_and_metrics(
    smoke: tuple[Experiment, SweepReport],
) -> None:
    exp, rep = smoke
    assert (rep.total, rep.ran, rep.skipped, rep.errors) == (12, 12, 0, 0)
    rows = _csv(rep.out / "results.csv")
    assert len(rows) == 12 and len({r["run_id"] for r in rows}) == 12
    cells = {(r["network"], r["controller"]) for r in rows}
    assert len(cells) == 6
    assert {r["seed"] for r in rows} == {"1", "2"}
    for r in rows:
        assert r["status"] == "ok" and r["runtime"] == "inproc" and r["error"] == ""
        for m in (
            "travel_time_s",
            "xte_optimal_rms_m",
            "min_clearance_m",
            "reached_goal",
            "control_actions",
            "control_actions_on_path",
            "success",
            "net_sent",
        ):
            assert r[m] != "", (m, r["run_id"])
        assert len(r["trajectory_sha256"]) == 64
        assert (rep.out / "runs" / r["run_id"] / "metrics.json").exists()
    ideal = [r for r in rows if r["network"] == "ideal"]
    lossy = [r for r in rows if r["network"] == "loss20"]
    assert all(float(r["net_delivery_ratio"]) == 1.0 for r in ideal)
    # 20 % Bernoulli loss on every link: the delivered share is 0.8 give or take sampling
    assert all(0.74 < float(r["net_delivery_ratio"]) < 0.86 for r in lossy)


def test_summary_has_each_cell_with_its_intervals_and_plots_exist(
    smoke: tuple[Experiment, SweepReport],
) -> None:
    exp, rep = smoke
    text = (rep.out / "summary.md").read_text()
    for net in ("ideal", "loss20"):
        for ctrl in ("nurbs", "backstepping", "fuzzy_pid"):
            assert f"| {net} | {ctrl} | 2 ⚠ | 0 |" in text  # 2 seeds: under the warning
    assert "cells rest on fewer than 10 runs** (2; marked ⚠)" in text
    rows = _csv(rep.out / "results.csv")
    summary = _csv(rep.out / "summary.csv")
    for net, ctrl, metric in (
        ("ideal", "nurbs", "xte_optimal_rms_m"),
        ("loss20", "fuzzy_pid", "min_clearance_m"),
    ):
        vals = [float(r[metric]) for r in rows if (r["network"], r["controller"]) == (net, ctrl)]
        want = bootstrap_ci(vals)
        (got,) = [
            s
            for s in summary
            if (s["network"], s["controller"], s["metric"]) == (net, ctrl, metric)
        ]
        assert float(got["mean"]) == pytest.approx(want.mean, rel=1e-12)
        assert float(got["ci_low"]) == pytest.approx(want.low, rel=1e-12)
        assert int(got["n"]) == 2
    for name in PLOTS:
        png = rep.out / "plots" / f"{name}.png"
        assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and png.stat().st_size > 10_000


def test_a_sweep_run_equals_a_plain_run_of_the_same_scenario(
    smoke: tuple[Experiment, SweepReport],
) -> None:
    _, rep = smoke
    (row,) = [
        r
        for r in _csv(rep.out / "results.csv")
        if (r["network"], r["controller"], r["seed"]) == ("ideal", "fuzzy_pid", "2")
    ]
    s, _ = load_scenario(SMALL, ["network.default={}", 'controller.kind="fuzzy_pid"'], seed=2)
    assert run_inproc(s).metrics.trajectory_sha256 == row["trajectory_sha256"]


def test_rerunning_a_finished_sweep_runs_nothing(smoke: tuple[Experiment, SweepReport]) -> None:
    exp, rep = smoke
    before = (rep.out / "results.csv").read_bytes()
    again = run_sweep(
        exp,
        str(SMOKE),
        SweepOptions(out=rep.out, runtime="inproc", jobs=1, rich=False, plots=False),
    )
    assert (again.ran, again.skipped) == (0, 12)
    assert (rep.out / "results.csv").read_bytes() == before


def test_a_dask_cluster_runs_the_same_runs(
    smoke: tuple[Experiment, SweepReport], tmp_path: Path
) -> None:
    # lockstep: the runs go to the cluster's workers as inproc ones do, and Dask workers are
    # daemonic, so a lockstep run there spawns its services (no fork server)
    runtime = "lockstep"
    from distributed import LocalCluster

    exp, rep = smoke
    axis = dataclasses.replace(exp.axes[0], values=exp.axes[0].values[:1])
    sub = dataclasses.replace(exp, controllers=("backstepping",), seeds=1, axes=(axis,))
    with LocalCluster(
        n_workers=2, processes=True, threads_per_worker=1, dashboard_address=None
    ) as cluster:
        got = run_sweep(
            sub,
            "sub",
            SweepOptions(
                out=tmp_path, runtime=runtime, rich=False, scheduler=cluster.scheduler_address
            ),
        )
    assert (got.total, got.ran, got.errors) == (1, 1, 0)
    assert len(got.rows) == 1  # the loop below checks every run, not none
    local = {r["run_id"]: r["trajectory_sha256"] for r in rep.rows}
    for r in got.rows:  # same run ids as the local sweep, bit-identical trajectories
        assert local[r["run_id"]] == r["trajectory_sha256"]


def test_a_failed_run_is_recorded_with_its_error(tmp_path: Path) -> None:
    p = tmp_path / "exp.toml"
    p.write_text(
        f'name = "fail"\nscenario = "{SMALL}"\nseeds = 1\ncontrollers = ["fuzzy_pid"]\n'
        '[[axes]]\nname = "m"\n[[axes.values]]\nlabel = "ok"\n'
        '[[axes.values]]\nlabel = "broken"\n'
        # valid as a scenario (only a mission checks its own parameters, when it is built):
        # the run fails, not the sweep
        'set = { "run.mission" = "testloop", "run.mission_params" = { crash_service = "x" } }\n'
    )
    out = tmp_path / "out"
    code = main(["sweep", str(p), "--runtime", "inproc", "--jobs", "1", "--out", str(out)])
    assert code == 1  # the sweep finished, but not every run did
    rows = {r["m"]: r for r in _csv(out / "results.csv")}
    assert rows["ok"]["status"] == "ok" and rows["ok"]["error"] == ""
    assert rows["broken"]["status"] == "error"
    assert "run.mission_params.crash_service: must be one of" in rows["broken"]["error"]
    assert "Traceback" in (out / "runs" / rows["broken"]["run_id"] / "error.txt").read_text()
    assert "## Failed runs" in (out / "summary.md").read_text()
    assert math.isfinite(float(rows["ok"]["travel_time_s"]))
