"""Benchmark fleet scaling: wall time per simulated vehicle-second against one vehicle's.

N vehicles (1, 2, 4, 8, 16) cross open water in parallel lanes 6 m apart, west to east, each
with its own sensor, estimator, planner and vehicle, each seeing the others (sonar) and
hearing their intents (pose and path): the fleet's whole dataflow, N x 4 services and
N (N - 1) x 3 links between vehicles. Each run is `--seconds` of mission time; the cost of a
fleet is its wall time over N x seconds (vehicle-seconds), and its scaling ratio
cost(N) / cost(1) (goal <= 1.3: linear in N). The baseline, one vehicle, is measured in the
same run, after a warm-up run. Inproc runs every N; lockstep (one process per service, the
clock over Zenoh) runs N up to --lockstep-max (default 8: 33 processes).
"""

from __future__ import annotations

import argparse
import time
from typing import Any

from common.config.scenario import Scenario, scenario_from_raw
from common.runtime.distributed.lockstep import run_lockstep
from common.runtime.model.inproc import run_inproc
from common.world.check import check_scenario

LANE_M = 6.0  # between two vehicles' lanes: hull to hull 5 m, well clear of rho0


def fleet_raw(n: int, seconds: float) -> dict[str, Any]:
    """A scenario of n vehicles in lanes across open water, for `seconds` of mission."""
    height = LANE_M * (n + 1)
    return {
        "run": {"name": f"bench-fleet{n}", "vehicle": "fleet", "max_time_s": seconds},
        "runtime": {"kind": "inproc"},
        "world": {
            "area": {"x_min_m": 0.0, "x_max_m": 100.0, "y_min_m": 0.0, "y_max_m": height},
            "start": {"x_m": 5.0, "y_m": LANE_M},
            "goal": {"x_m": 95.0, "y_m": LANE_M},
        },
        "vehicles": [
            {
                "id": f"auv{i + 1}",
                "start": {"x_m": 5.0, "y_m": LANE_M * (i + 1)},
                "goal": {"x_m": 95.0, "y_m": LANE_M * (i + 1)},
            }
            for i in range(n)
        ],
    }


def _timed(run: Any) -> float:
    t0 = time.perf_counter()
    run()
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="1,2,4,8,16", help="fleet sizes (default 1,2,4,8,16)")
    ap.add_argument("--seconds", type=float, default=20.0, help="mission seconds per run")
    ap.add_argument("--lockstep-max", type=int, default=8, help="largest N run in lockstep")
    a = ap.parse_args()
    sizes = sorted({int(x) for x in a.sizes.split(",")} | {1})
    rows = []
    for runtime in ("inproc", "lockstep"):
        # warm: imports, the first plan's set-up and (lockstep) the fork server, not measured
        warm = fleet_raw(1, min(a.seconds, 5.0))
        warm["runtime"]["kind"] = runtime
        ws = scenario_from_raw(warm, "warm-up", check=check_scenario)
        run_inproc(ws) if runtime == "inproc" else run_lockstep(ws, warm)
        base = None
        for n in sizes:
            if runtime == "lockstep" and n > a.lockstep_max:
                continue
            raw = fleet_raw(n, a.seconds)
            raw["runtime"]["kind"] = runtime
            s: Scenario = scenario_from_raw(raw, f"fleet{n}", check=check_scenario)
            if runtime == "inproc":
                wall = _timed(lambda s=s: run_inproc(s))
            else:
                wall = _timed(lambda s=s, raw=raw: run_lockstep(s, raw))
            per = wall / (n * a.seconds)
            base = per if n == 1 else base
            assert base is not None
            rows.append((runtime, n, wall, per, per / base))
            print(
                f"{runtime:8s} N={n:2d}  wall {wall:7.1f} s  {1e3 * per:7.1f} ms per "
                f"vehicle-second  cost(N)/(N cost(1)) = {per / base:5.2f}  "
                f"({a.seconds * n / wall:5.1f} vehicle-s per s)",
                flush=True,
            )
    print("\nruntime   N   wall (s)  ms/vehicle-s  scaling (goal <= 1.3)")
    for runtime, n, wall, per, ratio in rows:
        print(f"{runtime:8s} {n:2d}  {wall:8.1f}  {1e3 * per:12.1f}  {ratio:7.2f}")


if __name__ == "__main__":
    main()
