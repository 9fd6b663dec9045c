"""Run an experiment's grid, resumably: results.csv as runs finish, then summary and plots."""

from __future__ import annotations

import dataclasses
import json
import os
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from common.config.budget import DEFAULT_BUDGET
from common.jsonsafe import json_safe
from services.experiments.sweep.execute import run_all
from services.experiments.sweep.grid import Plan, RunSpec, expand
from services.experiments.sweep.plots import plot_sweep
from services.experiments.sweep.progress import SweepProgress
from services.experiments.sweep.results import ResultsFile
from services.experiments.sweep.schema import Experiment
from services.experiments.sweep.summary import aggregate, write_summary
from services.experiments.sweep.worker import RunOutcome, row_of


@dataclass(frozen=True, kw_only=True)
class SweepOptions:
    """How and where to run a sweep."""

    out: Path
    runtime: str = "lockstep"  # lockstep | inproc
    jobs: int = 1  # local parallel runs (ignored with a scheduler)
    scheduler: str = ""  # Dask scheduler address, e.g. tcp://10.0.0.5:8786
    keep_trajectories: bool = False  # save DIR/runs/<id>/trajectory.npz
    retry_errors: bool = False  # rerun runs recorded as failed
    plots: bool = True
    rich: bool | None = None  # progress bar: None = only on a terminal
    budget: float = 1.0  # scales every run's work budget (common/config/budget.py)


@dataclass(frozen=True, kw_only=True)
class SweepReport:
    """What a sweep did: runs in the plan, skipped as already done, run now, failed overall."""

    total: int
    skipped: int
    ran: int
    errors: int
    out: Path
    rows: list[dict[str, str]] = field(default_factory=list)  # this plan's rows, grid order


def plan_sweep(exp: Experiment, file: str, opts: SweepOptions) -> Plan:
    """Expand and validate every cell (raises ConfigError before anything runs)."""
    return expand(
        exp,
        file,
        runtime=opts.runtime,
        log_root=opts.out / "runs",
        keep_trajectory=opts.keep_trajectories,
        budget=DEFAULT_BUDGET.scaled(opts.budget),
    )


def run_sweep(exp: Experiment, file: str, opts: SweepOptions) -> SweepReport:
    """Run every run of the plan not yet in DIR/results.csv, then write the summary and plots."""
    plan = plan_sweep(exp, file, opts)
    out = opts.out
    out.mkdir(parents=True, exist_ok=True)
    _write_plan(plan, out / "experiment.json")
    grid = tuple(a.name for a in exp.all_axes)
    results = ResultsFile(out / "results.csv", grid_columns=grid)
    ids = {s.run_id for s in plan.runs}
    if opts.retry_errors:
        results.drop(results.ids("error") & ids)
    done = results.ids() & ids
    todo = [s for s in plan.runs if s.run_id not in done]

    with SweepProgress(len(todo), title=f"sweep {exp.name}", rich=opts.rich) as prog:

        def on_done(spec: RunSpec, outcome: RunOutcome) -> None:
            _save_run(out / "runs" / spec.run_id, outcome)
            stamp = datetime.now(UTC).isoformat(timespec="milliseconds")
            results.append(row_of(spec, outcome, plan.runtime, stamp))
            prog.done(
                f"{spec.cell} seed={spec.seed} [{spec.run_id}] {outcome.wall_s:.1f} s",
                outcome.status == "ok",
            )

        run_all(todo, on_done, jobs=opts.jobs, scheduler=opts.scheduler)

    order = {s.run_id: i for i, s in enumerate(plan.runs)}
    rows = sorted((r for r in results.rows if r["run_id"] in ids), key=lambda r: order[r["run_id"]])
    errors = [r for r in rows if r.get("status") != "ok"]
    finish(plan, rows, out, plots=opts.plots)
    return SweepReport(
        total=len(plan.runs),
        skipped=len(done),
        ran=len(todo),
        errors=len(errors),
        out=out,
        rows=rows,
    )


def finish(plan: Plan, rows: list[dict[str, str]], out: Path, *, plots: bool = True) -> None:
    """summary.md, summary.csv and plots/ from the rows of this plan."""
    exp = plan.experiment
    grid = tuple(a.name for a in exp.all_axes)
    cells = aggregate(rows, grid)
    errors = [r for r in rows if r.get("status") != "ok"]
    intro = (
        f"Experiment `{exp.name}` ({plan.file}): {len(rows)} of {len(plan.runs)} runs "
        f"recorded ({len(rows) - len(errors)} ok, {len(errors)} failed), "
        f"{len(cells)} cells x {exp.seeds} seeds (from {exp.first_seed}), base scenario "
        f"`{exp.scenario}`, runtime {plan.runtime}."
    )
    write_summary(out, f"Sweep {exp.name}", intro, cells, grid, errors)
    if plots and exp.all_axes:
        axis = next(a for a in exp.all_axes if a.name == exp.plot_axis)
        plot_sweep(out, cells, axis, grid, exp.name)


def _write_plan(plan: Plan, path: Path) -> None:
    """The resolved experiment and its run ids, for the record."""
    doc = {
        "experiment": dataclasses.asdict(plan.experiment),
        "file": plan.file,
        "runtime": plan.runtime,
        "runs": [{"run_id": s.run_id, "labels": s.labels, "seed": s.seed} for s in plan.runs],
    }
    _atomic_write(path, json.dumps(json_safe(doc), indent=1))


def _atomic_write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    with tmp.open("w") as fh:
        fh.write(text)
        fh.flush()
        os.fsync(fh.fileno())
    tmp.replace(path)


def _save_run(folder: Path, outcome: RunOutcome) -> None:
    """metrics.json, error.txt and trajectory.npz of one run (written before its CSV row)."""
    folder.mkdir(parents=True, exist_ok=True)
    if outcome.metrics is not None:
        _atomic_write(
            folder / "metrics.json",
            json.dumps(outcome.metrics.to_json(), indent=2, sort_keys=True),
        )
    else:
        _atomic_write(folder / "error.txt", outcome.error)
    if outcome.trajectory:
        tmp = folder / "trajectory.tmp.npz"
        np.savez_compressed(tmp, **outcome.trajectory)  # type: ignore[arg-type]
        tmp.replace(folder / "trajectory.npz")
