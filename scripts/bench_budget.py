"""Benchmark the work estimates (common/config/work.py) against what replans and runs take.

1. One replan on the default field per resolution, each in a fresh process: the budget's
   estimate of its peak memory beside the process's resident growth (ru_maxrss) and the
   peak Python's allocator traced (tracemalloc, a second process), and the replan's time.
2. Inproc runs of the default mission, with finer vehicle and estimator steps: the estimated
   wall time beside the measured CPU time, and the messages of the record.
The unit costs in common/config/work.py were read off these numbers.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import subprocess
import sys
import time
import tracemalloc
from pathlib import Path

from common.config.planner import PlannerConfig
from common.config.scenario import Scenario, load_scenario
from common.config.work import estimate
from services.planner.plan import PlanRequest, plan_path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "configs" / "default.toml"
RUN_SETS = (
    (),
    ("vehicle.dt_internal_s=0.001",),
    ("estimator.max_predict_dt_s=0.002",),
    ('estimator.vehicle_filter="ukf"', "estimator.max_predict_dt_s=0.01"),
)


def one_replan(res: float, connectivity: int, search: str, traced: bool) -> dict[str, float]:
    """One replan of the default field in this (fresh) process: its memory and time."""
    s, _ = load_scenario(DEFAULT)
    req = PlanRequest.across(s.world, s.vehicle)
    cfg = PlannerConfig(resolution_m=res, connectivity=connectivity, search=search)
    rss0 = _peak_rss()
    if traced:
        tracemalloc.start()
    t0 = time.perf_counter()
    ok = plan_path(req, cfg).ok
    wall = time.perf_counter() - t0
    peak = tracemalloc.get_traced_memory()[1] if traced else 0
    rss = _peak_rss() - rss0
    return {"ok": ok, "wall_s": wall, "traced": peak, "rss": rss}


def _peak_rss() -> float:
    """This process's peak resident set (bytes): VmHWM, whose high-water mark starts afresh at
    exec (ru_maxrss carries the parent's size over a fork and exec)."""
    try:
        status = Path("/proc/self/status").read_text()
    except OSError:
        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024.0  # KiB on Linux
    line = next(x for x in status.splitlines() if x.startswith("VmHWM:"))
    return float(line.split()[1]) * 1024.0


def _child(res: float, connectivity: int, search: str, traced: bool) -> dict[str, float]:
    args = [sys.executable, __file__, "--child", str(res), str(connectivity), search]
    # the child imports this checkout's code, whatever is installed
    env = dict(
        os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])
    )
    out = subprocess.run(
        args + (["--traced"] if traced else []), capture_output=True, text=True, env=env
    )
    if out.returncode != 0:
        raise RuntimeError(out.stderr)
    result: dict[str, float] = json.loads(out.stdout)
    return result


def bench_replans(
    resolutions: list[float], searches: list[tuple[str, int]]
) -> list[tuple[str, int, float, float]]:
    """Print the table; returns (search, K, resolution, measured rss / estimate) per row."""
    rows = []
    print("one replan, default field: estimate vs measured (fresh process each)")
    print(
        f"{'search':>8s} {'K':>3s} {'res m':>7s} {'cells':>9s} {'estimate':>9s} "
        f"{'rss':>9s} {'traced':>9s} {'rss/est':>7s} {'B/cell':>7s} {'replan':>8s}"
    )
    for search, k in searches:
        for res in resolutions:
            s = Scenario(planner=PlannerConfig(resolution_m=res, connectivity=k, search=search))
            est = estimate(s)
            m = _child(res, k, search, traced=False)
            t = _child(res, k, search, traced=True)
            mib = 2**20
            print(
                f"{search:>8s} {k:3d} {res:7.4g} {est.grid_cells:9.3g} "
                f"{est.planner_bytes / mib:7.1f}Mi {m['rss'] / mib:7.1f}Mi "
                f"{t['traced'] / mib:7.1f}Mi {m['rss'] / est.planner_bytes:7.2f} "
                f"{m['rss'] / est.grid_cells:7.0f} {m['wall_s']:7.2f}s"
            )
            rows.append((search, k, res, m["rss"] / est.planner_bytes))
    return rows


def bench_runs(max_time_s: float) -> None:
    from common.runtime.model.inproc import run_inproc

    print(f"\ninproc runs of the default mission, {max_time_s:g} s: estimate vs measured")
    print(f"{'overrides':64s} {'est wall':>9s} {'cpu':>7s} {'est msgs':>9s} {'msgs':>7s}")
    run_inproc(load_scenario(DEFAULT, ['runtime.kind="inproc"', "run.max_time_s=2"])[0])  # warm
    for sets in RUN_SETS:
        overrides = ['runtime.kind="inproc"', f"run.max_time_s={max_time_s}", *sets]
        s, _ = load_scenario(DEFAULT, overrides)
        est = estimate(s)
        c0 = time.process_time()
        result = run_inproc(s)
        cpu = time.process_time() - c0
        print(
            f"{' '.join(sets) or '(default)':64s} {est.wall_s:8.2f}s {cpu:6.2f}s "
            f"{est.messages:9.0f} {result.record.count:7d}"
        )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--resolutions", type=float, nargs="+", default=[0.5, 0.25, 0.125, 0.0625])
    ap.add_argument("--max-time", type=float, default=30.0, help="mission seconds of each run")
    ap.add_argument("--child", nargs=3, metavar=("RES", "K", "SEARCH"), help=argparse.SUPPRESS)
    ap.add_argument("--traced", action="store_true", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child:
        res, k, search = a.child
        print(json.dumps(one_replan(float(res), int(k), search, a.traced)))
        sys.exit(0)
    bench_replans(a.resolutions, [("dijkstra", 8), ("dijkstra", 16)])
    bench_replans([r for r in a.resolutions if r >= 0.125], [("astar", 8)])
    bench_runs(a.max_time)
