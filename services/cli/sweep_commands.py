"""The experiment sub-commands: sweep (a grid of runs), reproduce (the paper's section 4) and
network-report (the networked-control sweeps, docs/networked-control)."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
from pathlib import Path
from typing import TypedDict

from services.cli.flags import Subparsers, budget_arg, command

# the same as services.experiments.reproduction.reproduce.CROSSING (imported lazily: the CLI
# starts fast)
CROSSING = Path("configs/experiments/scenarios/crossing.toml")


def _jobs(text: str) -> int:
    n = int(text)
    if n < 1:
        raise argparse.ArgumentTypeError("--jobs must be >= 1")
    return n


def _common(p: argparse.ArgumentParser, runtime: str = "lockstep") -> None:
    p.add_argument(
        "--jobs",
        type=_jobs,
        default=os.cpu_count() or 1,
        help="runs in parallel on this machine (default: the number of cores)",
    )
    p.add_argument(
        "--runtime",
        choices=("lockstep", "inproc"),
        default=runtime,
        help="lockstep: every service its own process over Zenoh; inproc: one process, "
        f"bit-identical and faster (default: {runtime})",
    )
    p.add_argument(
        "--scheduler",
        default="",
        metavar="ADDRESS",
        help="run on a Dask distributed cluster, e.g. tcp://10.0.0.5:8786",
    )


class RunOptions(TypedDict):
    """The experiment options' fields _common's arguments give."""

    runtime: str
    jobs: int
    scheduler: str


class ReportOptions(RunOptions):
    """The options every report command shares: _report_dirs' and _common's arguments, and
    the command line that regenerates the report."""

    out: Path
    report_dir: Path
    command: str


def _run_options(a: argparse.Namespace) -> RunOptions:
    """What _common's arguments say, as the experiment options' fields."""
    return RunOptions(runtime=a.runtime, jobs=a.jobs, scheduler=a.scheduler)


def _report_options(a: argparse.Namespace) -> ReportOptions:
    """The options every report command shares (ReportOptions)."""
    return ReportOptions(
        out=a.out,
        report_dir=a.report_dir,
        **_run_options(a),
        command=_regenerate_command(sys.argv[1:]),
    )


def _report_dirs(p: argparse.ArgumentParser, runs: str, docs: str) -> None:
    """--out (the runs, resumable) and --report-dir (REPORT.md and figures/)."""
    p.add_argument(
        "--out",
        type=Path,
        default=Path("runs") / runs,
        help=f"the runs (default runs/{runs}); rerun to resume",
    )
    p.add_argument(
        "--report-dir",
        type=Path,
        default=Path("docs") / docs,
        help=f"where REPORT.md and its figures go (default docs/{docs}, the committed report)",
    )


def cmd_sweep(a: argparse.Namespace) -> int:
    """run an experiment grid (profiles x controllers x seeds)"""
    from services.experiments.sweep.run import SweepOptions, run_sweep
    from services.experiments.sweep.schema import load_experiment

    exp = load_experiment(a.experiment)
    out = a.out or Path("runs") / f"sweep-{exp.name}"
    opts = SweepOptions(
        out=out,
        **_run_options(a),
        keep_trajectories=a.keep_trajectories,
        retry_errors=a.retry_errors,
        plots=not a.no_plots,
        budget=a.budget,
    )
    rep = run_sweep(exp, str(a.experiment), opts)
    print(
        f"sweep {exp.name}: {rep.total} runs, {rep.skipped} already done, {rep.ran} run now, "
        f"{rep.errors} failed; {out / 'results.csv'}, {out / 'summary.md'}"
    )
    return 1 if rep.errors else 0


def cmd_reproduce(a: argparse.Namespace) -> int:
    """the paper's section-4 comparison and DIR/REPORT.md"""
    from services.experiments.reproduction.reproduce import ReproduceOptions, reproduce

    opts = ReproduceOptions(
        **_report_options(a),
        crossing=None if str(a.crossing) == "none" else a.crossing,
        scenario=a.scenario,
        seeds=a.seeds,
        tune=a.tune,
        tune_seeds=a.tune_seeds,
        replan=a.replan,
    )
    res = reproduce(opts)
    errors = res.sweep.errors + (res.crossing.errors if res.crossing else 0)
    total = res.sweep.total + (res.crossing.total if res.crossing else 0)
    print(f"reproduce: {total} runs ({errors} failed); report {res.report}")
    return 1 if errors else 0


def _regenerate_command(argv: list[str]) -> str:
    """The command line a report says regenerates it, without where this run kept its runs.

    --out only names a folder (a temporary one, often): the report is the same without it.
    """
    kept: list[str] = []
    skip = False
    for arg in argv:
        if skip:
            skip = False
        elif arg == "--out":
            skip = True
        elif not arg.startswith("--out="):
            kept.append(arg)
    return "tidelink " + shlex.join(kept)


def _sweep_names(text: str) -> tuple[str, ...]:
    from services.experiments.netreport.networked import SWEEPS

    names = tuple(n.strip() for n in text.split(",") if n.strip())
    bad = [n for n in names if n not in SWEEPS]
    if bad or not names:
        raise argparse.ArgumentTypeError(
            f"--sweeps: {', '.join(bad) or 'none'} unknown, expected some of {', '.join(SWEEPS)}"
        )
    return names


def _seeds(text: str) -> int:
    n = int(text)
    if not 1 <= n <= 10_000:
        raise argparse.ArgumentTypeError("--seeds must be in 1..10000")
    return n


def cmd_network_report(a: argparse.Namespace) -> int:
    """the networked-control sweeps (delay, loss, bursts, outages x command sequences on/off x
    controllers) and DIR/REPORT.md"""
    from services.experiments.netreport.networked import NetworkOptions, network_report

    res = network_report(
        NetworkOptions(
            **_report_options(a),
            sweeps=a.sweeps,
            seeds=a.seeds,
            cost_steps=a.cost_steps,
            scenario=a.scenario,
        )
    )
    print(f"network-report: {res.runs} runs ({res.errors} failed); report {res.report}")
    return 1 if res.errors else 0


def register(sub: Subparsers) -> None:
    """Add sweep, reproduce and network-report to the tidelink parser."""
    _add_sweep(sub)
    _add_reproduce(sub)
    _add_network_report(sub)


def _add_sweep(sub: Subparsers) -> None:
    s = command(sub, "sweep", cmd_sweep)
    s.add_argument(
        "experiment", type=Path, help="experiment TOML, e.g. configs/experiments/delay.toml"
    )
    s.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder (default runs/sweep-<name>); rerun to resume",
    )
    _common(s)
    s.add_argument(
        "--retry-errors",
        action="store_true",
        help="rerun runs recorded as failed in DIR/results.csv",
    )
    s.add_argument(
        "--keep-trajectories", action="store_true", help="also save DIR/runs/<id>/trajectory.npz"
    )
    s.add_argument("--no-plots", action="store_true", help="skip DIR/plots/")
    budget_arg(s)


def _add_reproduce(sub: Subparsers) -> None:
    r = command(sub, "reproduce", cmd_reproduce)
    r.add_argument(
        "--scenario",
        type=Path,
        default=Path("configs/default.toml"),
        help="the scenario (default: configs/default.toml, the paper-like field)",
    )
    _report_dirs(r, "reproduce", "reproduce")
    r.add_argument(
        "--crossing",
        type=Path,
        default=CROSSING,
        help=f"the crossing-obstacles scenario (default {CROSSING}); 'none' skips it",
    )
    r.add_argument("--seeds", type=int, default=5, help="seeds per cell (default 5)")
    _common(r, runtime="inproc")  # bit-identical to lockstep (tested), and faster
    r.add_argument(
        "--no-tune",
        dest="tune",
        action="store_false",
        help="keep the scenario's gains instead of running the same gain search for each",
    )
    r.add_argument("--tune-seeds", type=int, default=2, help="seeds per tuning candidate")
    r.add_argument(
        "--replan",
        action="store_true",
        help="let the planner replan as in a mission (default: every controller follows the "
        "first plan, as in the paper)",
    )


def _add_network_report(sub: Subparsers) -> None:
    n = command(sub, "network-report", cmd_network_report)
    _report_dirs(n, "networked-control", "networked-control")  # runs: a folder per sweep
    n.add_argument(
        "--sweeps",
        type=_sweep_names,
        default=("delay", "loss", "burst", "outage"),
        help="which of configs/experiments/networked/*.toml (default delay,loss,burst,outage)",
    )
    n.add_argument(
        "--seeds",
        type=_seeds,
        default=None,
        help="seeds per cell (default: the experiment files', 20)",
    )
    n.add_argument(
        "--scenario",
        type=Path,
        default=None,
        help="run every sweep in this world instead (e.g. configs/ocean.toml, with its own "
        "time limit; default: the files' calm default.toml); give --out and --report-dir too",
    )
    _common(n, runtime="inproc")
    n.add_argument(
        "--cost-steps",
        type=int,
        default=200,
        help="planner steps timed per controller and horizon for the cost table (default 200)",
    )
