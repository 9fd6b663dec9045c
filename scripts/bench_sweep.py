"""Benchmark sweep throughput: runs per minute of the default mission, inproc and lockstep."""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc
from services.experiments.schema import Experiment
from services.experiments.sweep import SweepOptions, run_sweep

ROOT = Path(__file__).resolve().parents[1]


def bench(runtime: str, exp: Experiment, jobs: int) -> tuple[float, int]:
    """Wall seconds for the whole sweep (process start-up included) and its failed runs."""
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        t0 = time.monotonic()
        rep = run_sweep(
            exp,
            "bench",
            SweepOptions(out=Path(tmp), runtime=runtime, jobs=jobs, rich=False, plots=False),
        )
        return time.monotonic() - t0, rep.errors


def main(scenario: Path, seeds: int, jobs: int, runtimes: list[str]) -> dict[str, float]:
    """Print runs/minute per runtime beside a serial inproc baseline; return runs/minute."""
    exp = Experiment(
        name="bench",
        scenario=str(scenario.resolve()),
        seeds=seeds,
        controllers=("nurbs", "backstepping", "fuzzy_pid"),
    )
    n = exp.n_runs()
    s, _ = load_scenario(scenario, ['runtime.kind="inproc"'])
    t0 = time.monotonic()
    run_inproc(s)  # baseline: one run, serially, in this process
    single_s = time.monotonic() - t0
    print(
        f"scenario {scenario}, {n} runs per runtime (3 controllers x {seeds} seeds), "
        f"--jobs {jobs}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}"
    )
    print(
        f"baseline: one serial inproc run (nurbs, seed 1) {single_s:.1f} s "
        f"= {60 / single_s:.1f} runs/min"
    )
    out = {}
    for runtime in runtimes:
        wall, errors = bench(runtime, exp, jobs)
        rpm = n / wall * 60
        out[runtime] = rpm
        print(
            f"{runtime:9s} {wall:7.1f} s for {n} runs = {rpm:5.1f} runs/min "
            f"({rpm * single_s / 60:.2f} x the serial baseline), {errors} failed"
        )
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--scenario", type=Path, default=ROOT / "configs" / "default.toml")
    ap.add_argument("--seeds", type=int, default=2, help="seeds per controller (default 2)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument(
        "--runtime",
        action="append",
        choices=("inproc", "lockstep"),
        help="repeatable; default both",
    )
    a = ap.parse_args()
    main(a.scenario, a.seeds, a.jobs, a.runtime or ["inproc", "lockstep"])
