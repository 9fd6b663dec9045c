"""Benchmark sweep throughput as users feel it: simulated seconds per wall second of a sweep.

The sweep of issue 63: the default mission, 12 seeds, NURBS, `--jobs 2`, once inproc and once
lockstep, process start-up included; then the same sweep of the ocean (configs/ocean.toml: its
current field, ocean plant and navigation), whose figures have no target of their own. Beside
the first, the per-tick floor: the lockstep runtime's own cost per tick (the toy loop of
trivial cores), against one raw Zenoh round trip through a router measured in the same run
and that round trip to three clients at once, and what that floor alone allows a sweep at the
mission's ticks per simulated second.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time
from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc
from services.experiments.sweep.run import SweepOptions, run_sweep
from services.experiments.sweep.schema import Experiment

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = (ROOT / "configs" / "default.toml", ROOT / "configs" / "ocean.toml")
# issue 63's goals for this sweep on the 2-core machine (simulated s per wall s, all jobs)
GOALS = {"inproc": 150.0, "lockstep": 60.0}


def bench(runtime: str, exp: Experiment, jobs: int) -> tuple[float, float, int]:
    """Wall seconds for the whole sweep (process start-up included), the simulated seconds
    its runs covered, and its failed runs."""
    with tempfile.TemporaryDirectory(prefix="bench-sweep-") as tmp:
        t0 = time.monotonic()
        rep = run_sweep(
            exp,
            "bench",
            SweepOptions(out=Path(tmp), runtime=runtime, jobs=jobs, rich=False, plots=False),
        )
        wall = time.monotonic() - t0
        sim = sum(float(r.get("t_end_s") or 0.0) for r in rep.rows)
        return wall, sim, rep.errors


def tick_floor(ticks_per_sim_s: float) -> None:
    """Print the lockstep tick floor (toy loop) against the raw transport."""
    # scripts/bench_runtime.py measures both (it needs the runtime self-test loop, a fixture
    # of tests/, which it finds itself); imported here only when asked for
    import bench_runtime

    bench_runtime._find_the_test_loop()
    floor_ms, _ = bench_runtime.bench_floor()
    print(
        f"per-tick floor: lockstep toy loop {floor_ms:.2f} ms per tick; "
        f"{bench_runtime.against_transport(floor_ms)}"
    )
    print(
        f"  the mission ticks {ticks_per_sim_s:.1f} times per simulated second: the runtime's "
        f"own cost alone allows at most {1e3 / (floor_ms * ticks_per_sim_s):.0f} simulated s "
        "per wall s per job"
    )


def main(
    scenario: Path,
    seeds: int,
    jobs: int,
    runtimes: list[str],
    controllers: tuple[str, ...] = ("nurbs",),
    floor: bool = False,
) -> dict[str, float]:
    """Print simulated seconds per wall second (and runs/minute) per runtime beside a serial
    inproc baseline; return simulated seconds per wall second per runtime."""
    exp = Experiment(
        name="bench", scenario=str(scenario.resolve()), seeds=seeds, controllers=controllers
    )
    n = exp.n_runs()
    s, _ = load_scenario(scenario, ['runtime.kind="inproc"'])
    t0 = time.monotonic()
    base = run_inproc(s)  # baseline: one run, serially, in this process
    single_s = time.monotonic() - t0
    print(
        f"scenario {scenario}, {n} runs per runtime ({' '.join(controllers)} x {seeds} seeds), "
        f"--jobs {jobs}, {os.cpu_count()} cores, load average {os.getloadavg()[0]:.1f}"
    )
    print(
        f"baseline: one serial inproc run (seed 1, in this process) {single_s:.2f} s for "
        f"{base.t_end:.1f} simulated s = {base.t_end / single_s:.1f} simulated s per wall s"
    )
    out = {}
    for runtime in runtimes:
        wall, sim, errors = bench(runtime, exp, jobs)
        rate = sim / wall
        out[runtime] = rate
        print(
            f"{runtime:9s} {wall:7.1f} s for {n} runs, {sim:.0f} simulated s = {rate:6.1f} "
            f"simulated s per wall s ({n / wall * 60:5.1f} runs/min), {errors} failed"
        )
    if floor:
        tick_floor(base.ticks / base.t_end)
    # the targets are the default mission's
    goals = scenario.resolve() == SCENARIOS[0]
    rows = ", ".join(
        f"{rt} {rate:.0f}"
        + (f" (target >= {GOALS[rt]:g}) {'OK' if rate >= GOALS[rt] else 'MISSED'}" if goals else "")
        for rt, rate in out.items()
    )
    print(
        f"result: sweep of {scenario.name}, {n} runs, --jobs {jobs}: simulated s per wall s: {rows}"
    )
    return out


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument(
        "--scenario",
        type=Path,
        action="append",
        help="repeatable; default configs/default.toml, then configs/ocean.toml",
    )
    ap.add_argument("--seeds", type=int, default=12, help="seeds per controller (default 12)")
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument(
        "--controller",
        action="append",
        choices=("nurbs", "backstepping", "fuzzy_pid"),
        help="repeatable; default nurbs",
    )
    ap.add_argument(
        "--runtime",
        action="append",
        choices=("inproc", "lockstep"),
        help="repeatable; default both",
    )
    ap.add_argument("--no-floor", action="store_true", help="skip the lockstep tick floor")
    a = ap.parse_args()
    for k, scenario in enumerate(a.scenario or SCENARIOS):
        main(
            scenario,
            a.seeds,
            a.jobs,
            a.runtime or ["inproc", "lockstep"],
            tuple(a.controller or ["nurbs"]),
            floor=not a.no_floor and k == 0,
        )
