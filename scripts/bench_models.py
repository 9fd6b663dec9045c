"""Benchmark the ocean's models (issue 60): what each costs a mission, against still water.

The default mission in the inproc runtime (one process, virtual time) is the baseline, run in
the same process; then the same mission with one model on at a time (a 0.3 m/s current with a
shear and an eddy; the REMUS 100 plant; DVL + AHRS + USBL navigation) and configs/ocean.toml
with all of them. For each: the wall time per simulated second (the median of --repeats runs,
the process's CPU clock), the ratio to the baseline, and the plant's integrator cost alone
(one RK4 step, timed in a loop), since that is where the REMUS model's work is.

    python scripts/bench_models.py [--repeats 3] [--max-time 40]
"""

from __future__ import annotations

import argparse
import statistics
import time
import timeit
from pathlib import Path

from common.config.scenario import load_scenario
from common.config.vehicle import VehicleConfig
from common.runtime.model.inproc import run_inproc
from common.world.check import check_scenario
from common.world.current import CurrentField
from services.vehicle.plant import make_plant

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT / "configs" / "default.toml"
OCEAN = ROOT / "configs" / "ocean.toml"
CURRENT = [
    "world.current.speed_mps=0.3",
    "world.current.direction_deg=90",
    "world.current.shear_mps=0.1",
    "world.current.eddies=[{x_m=58.0, y_m=20.0, radius_m=8.0, speed_mps=0.15}]",
]
CASES: tuple[tuple[str, Path, list[str]], ...] = (
    ("still water (default)", DEFAULT, []),
    ("+ current (shear, eddy)", DEFAULT, CURRENT),
    ("+ fossen3dof plant", DEFAULT, ['vehicle.model="fossen3dof"']),
    ("+ dvl_usbl navigation", DEFAULT, ['sensor.navigation="dvl_usbl"']),
    ("ocean.toml (all of them)", OCEAN, []),
)


def per_sim_second(path: Path, sets: list[str], max_time_s: float, repeats: int) -> float:
    """Median CPU seconds per simulated second of one inproc mission (ms)."""
    s, _ = load_scenario(path, [*sets, f"run.max_time_s={max_time_s}"], check=check_scenario)
    costs = []
    for _ in range(repeats):
        t0 = time.process_time()
        run_inproc(s)
        spent = time.process_time() - t0
        # the mission metrics never held t_end_s, so this was always max_time_s; kept so the
        # figures stay comparable (r.t_end is the end of a run that stops at its goal)
        sim = max_time_s
        costs.append(1e3 * spent / sim)
    return statistics.median(costs)


def rk4_us(model: str, current: bool) -> float:
    """One RK4 step of the plant (us), in still water or an eddying current."""
    cfg = VehicleConfig(model=model)  # type: ignore[arg-type]
    field = None
    if current:
        sc, _ = load_scenario(OCEAN)
        field = CurrentField(sc.world.current, sc.world.area, 1).velocity
    plant = make_plant(cfg, field)
    s0 = plant.initial(50.0, 20.0, 0.3, 1.5)
    n = 20000
    return 1e6 * timeit.timeit(lambda: plant.step(s0, 0.01, 3.0, 1.5, 0.1), number=n) / n


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--max-time", type=float, default=40.0)
    args = ap.parse_args()
    print(f"inproc mission cost per simulated second (first {args.max_time:g} s of the mission,")
    print(f"median of {args.repeats}, CPU time), against still water measured in the same run")
    print(f"{'case':28s} {'ms / sim s':>10s} {'x still':>8s} {'sim s / s':>9s}")
    base = None
    for name, path, sets in CASES:
        ms = per_sim_second(path, sets, args.max_time, args.repeats)
        base = ms if base is None else base
        print(f"{name:28s} {ms:10.1f} {ms / base:8.2f} {1e3 / ms:9.0f}")
    print()
    print("the plant's RK4 step (us), 100 per simulated second")
    print(f"{'plant':12s} {'still':>7s} {'current':>8s}")
    for model in ("unicycle", "fossen3dof"):
        print(f"{model:12s} {rk4_us(model, False):7.1f} {rk4_us(model, True):8.1f}")


if __name__ == "__main__":
    main()
