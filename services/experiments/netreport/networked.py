"""`tidelink network-report`: the networked-control sweeps and their REPORT.md.

Four experiment files (configs/experiments/networked/{delay,loss,burst,outage}.toml), each a
fault axis x command sequences on / off x the three controllers x seeds, run by the one sweep
engine (sweep.run.run_sweep: resumable, DIR/<sweep>/results.csv), aggregated per cell, drawn
(sweep.plots.plot_sweep: success, cross-track error, minimum clearance, time in HOLD or FAILSAFE
against the fault, a colour per controller, dashed without sequences) and written up with
the cost of the sequences (sequence_cost.py) in REPORT_DIR/REPORT.md (report.py).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path

from services.experiments.netreport.goals import SweepCells
from services.experiments.netreport.report import write_report
from services.experiments.netreport.sequence_cost import HORIZONS_S, CostRow, cost_table
from services.experiments.sweep.plots import plot_sweep
from services.experiments.sweep.results import as_number
from services.experiments.sweep.run import SweepOptions, run_sweep
from services.experiments.sweep.schema import Experiment, load_experiment
from services.experiments.sweep.summary import aggregate

SWEEPS = ("delay", "loss", "burst", "outage")
EXPERIMENTS = Path("configs/experiments/networked")
MECHANISM = "mechanism"  # the axis of the experiment files: "on" (sequences) / "off"
BLIND = "blind_time_s"  # derived: time in HOLD or FAILSAFE
# the figures of each sweep: metric -> y label
FIGURES = {
    "success": "success rate (goal, no contact, never inside rho0)",
    "xte_planned_rms_m": "cross-track error to the path in force, RMS (m)",
    "min_clearance_m": "minimum clearance, eq. (12) (m)",
    BLIND: "time in HOLD or FAILSAFE (s)",
}


@dataclass(frozen=True, kw_only=True)
class NetworkOptions:
    """What `tidelink network-report` runs and where it writes."""

    out: Path = Path("runs/networked-control")  # the runs: DIR/<sweep>/results.csv, ...
    report_dir: Path = Path("docs/networked-control")  # REPORT.md and figures/
    experiments: Path = EXPERIMENTS
    sweeps: tuple[str, ...] = SWEEPS
    seeds: int | None = None  # None: the experiment files' own (20)
    # the world every sweep runs in, in place of the experiment files' (None: theirs, the
    # calm default.toml); the report says which, so calm and ocean reports sit side by side
    scenario: Path | None = None
    runtime: str = "inproc"
    jobs: int = 1
    scheduler: str = ""
    cost_steps: int = 200  # planner steps timed per (controller, horizon)
    cost_horizons: tuple[float, ...] = HORIZONS_S  # the first is the ratios' baseline
    rich: bool | None = None
    command: str = ""  # the command line, for the report


@dataclass(frozen=True, kw_only=True)
class NetworkResult:
    report: Path
    runs: int
    errors: int


def with_blind_time(row: dict[str, str]) -> dict[str, str]:
    """A results row with time in HOLD or FAILSAFE (hold_time_s + failsafe_time_s) added."""
    hold, fail = as_number(row.get("hold_time_s")), as_number(row.get("failsafe_time_s"))
    return {**row, BLIND: repr(hold + fail)} if row.get("status") == "ok" else row


def in_world(exp: Experiment, scenario: Path) -> Experiment:
    """`exp` run in `scenario` (`--scenario`), with the scenario's own time limit: the files'
    120 s is the calm field's slowest success."""
    kept = {k: v for k, v in exp.set.items() if k != "run.max_time_s"}
    return dataclasses.replace(exp, scenario=str(scenario.resolve()), set=kept)


def run_sweeps(opts: NetworkOptions) -> list[SweepCells]:
    """Run (or resume) every sweep and draw its figures into REPORT_DIR/figures/<sweep>/."""
    out = []
    for name in opts.sweeps:
        file = opts.experiments / f"{name}.toml"
        exp = load_experiment(file)
        if opts.seeds is not None:
            exp = dataclasses.replace(exp, seeds=opts.seeds)
        if opts.scenario is not None:
            exp = in_world(exp, opts.scenario)
        rep = run_sweep(
            exp,
            str(file),
            SweepOptions(
                out=opts.out / name,
                runtime=opts.runtime,
                jobs=opts.jobs,
                scheduler=opts.scheduler,
                plots=False,
                rich=opts.rich,
            ),
        )
        grid = tuple(a.name for a in exp.all_axes)
        cells = aggregate([with_blind_time(r) for r in rep.rows], grid)
        axis = next(a for a in exp.all_axes if a.name == exp.plot_axis)
        files = plot_sweep(
            opts.report_dir,
            cells,
            axis,
            grid,
            f"{name}, {exp.seeds} seeds",
            metrics=FIGURES,
            folder=f"figures/{name}",
            dash_axis=MECHANISM,
        )
        out.append(
            SweepCells(
                name=name,
                file=str(file),
                axis=axis,
                seeds=exp.seeds,
                first_seed=exp.first_seed,
                cells=cells,
                runs=rep.total,
                errors=rep.errors,
                figures=[str(f.relative_to(opts.report_dir)) for f in files],
            )
        )
    return out


def network_report(opts: NetworkOptions) -> NetworkResult:
    """Run the sweeps, measure the sequences' cost, write REPORT_DIR/REPORT.md."""
    sweeps = run_sweeps(opts)
    cost: list[CostRow] = cost_table(opts.cost_steps, opts.cost_horizons)
    opts.report_dir.mkdir(parents=True, exist_ok=True)
    path = opts.report_dir / "REPORT.md"
    world = "configs/default.toml (calm water)" if opts.scenario is None else str(opts.scenario)
    write_report(path, sweeps, cost, runtime=opts.runtime, command=opts.command, world=world)
    return NetworkResult(
        report=path, runs=sum(s.runs for s in sweeps), errors=sum(s.errors for s in sweeps)
    )
