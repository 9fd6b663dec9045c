"""A series of realtime fleet launches as a user runs them: does every one end clean?

Each seed is `tidelink launch configs/fleet4.toml --seed S --record` at the scenario's own
time scale (1x): 16 supervised service processes, the router and the clock on this machine.
One row per launch: its exit code and outcome, how many vehicles reached their goals, the
nearest any hull came to an obstacle (min clearance; < 0 is contact) and to rho0, the
nearest two hulls came, how many vehicle periods the services skipped (fell behind) and the
CPU the launch used (busy cores over its wall time, from /proc/stat: run it on an otherwise
idle machine). Every launch's folder (metrics.json, run.mcap, logs/) is kept under --out, so
a launch that fails can be replayed (`tidelink replay`) and read (`tidelink metrics`).

    scripts/bench fleet_launches --seeds 60-69
"""

from __future__ import annotations

import argparse
import json
import re
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SKIPPED = re.compile(r"skipped (\d+) periods in all")


def seeds_of(text: str) -> list[int]:
    """'60-69' or '54,60,61' as a list of seeds."""
    out: list[int] = []
    for part in text.split(","):
        lo, _, hi = part.partition("-")
        out += list(range(int(lo), int(hi or lo) + 1))
    return out


def busy_jiffies() -> tuple[int, int]:
    """(busy, total) CPU jiffies of the whole machine since boot."""
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]  # idle + iowait
    return sum(fields) - idle, sum(fields)


def launch(scenario: Path, seed: int, out: Path, extra: list[str]) -> dict[str, Any]:
    """One launch; what its metrics, logs and the machine's CPU counters say."""
    argv = [sys.executable, "-m", "services.cli", "launch", str(scenario), "--seed", str(seed)]
    argv += ["--record", "--no-plot", "--json", "--out", str(out), *extra]
    b0, t0 = busy_jiffies()
    w0 = time.monotonic()
    proc = subprocess.run(argv, cwd=ROOT, capture_output=True, text=True, check=False)
    wall = time.monotonic() - w0
    b1, t1 = busy_jiffies()
    cores = len(Path("/proc/stat").read_text().split("\ncpu")) - 1
    m: dict[str, Any] = {}
    if (out / "metrics.json").exists():
        m = json.loads((out / "metrics.json").read_text())
    skipped = sum(
        int(g) for log in (out / "logs").glob("*.log") for g in SKIPPED.findall(log.read_text())
    )
    vehicles = m.get("vehicles", {})
    return {
        "seed": seed,
        "exit": proc.returncode,
        "outcome": m.get("outcome", "-"),
        "reached": m.get("vehicles_reached", 0),
        "of": len(vehicles),
        "min_clearance_m": min((v["min_clearance_m"] for v in vehicles.values()), default=None),
        "rho0_breach_m": m.get("rho0_breach_m"),
        "contact": m.get("collisions", 0) + m.get("vehicle_collisions", 0),
        "min_separation_m": m.get("min_separation_m"),
        "skipped": skipped,
        "cores_busy": cores * (b1 - b0) / max(1, t1 - t0),
        "wall_s": wall,
        "error": "" if m else proc.stderr[-400:],
    }


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument("--seeds", default="60-69", help="seeds, e.g. 60-69 or 54,60 (default 60-69)")
    ap.add_argument("--scenario", type=Path, default=ROOT / "configs" / "fleet4.toml")
    ap.add_argument("--out", type=Path, default=ROOT / "runs" / "fleet-launches")
    ap.add_argument("extra", nargs="*", help="more `tidelink launch` arguments (after --)")
    a = ap.parse_args()
    rows = []
    print(
        f"{'seed':>4} {'exit':>4} {'outcome':<12} {'goals':>5} {'min clr m':>9} {'rho0 brch':>9} "
        f"{'contact':>7} {'min sep m':>9} {'skipped':>7} {'cores':>5} {'wall s':>6}"
    )
    for seed in seeds_of(a.seeds):
        r = launch(a.scenario, seed, a.out / f"s{seed}", a.extra)
        rows.append(r)
        clr = "-" if r["min_clearance_m"] is None else f"{r['min_clearance_m']:.2f}"
        sep = "-" if r["min_separation_m"] is None else f"{r['min_separation_m']:.2f}"
        print(
            f"{r['seed']:>4} {r['exit']:>4} {r['outcome']:<12} {r['reached']:>2}/{r['of']:<2} "
            f"{clr:>9} {r['rho0_breach_m'] or 0.0:>9.2f} {r['contact']:>7} {sep:>9} "
            f"{r['skipped']:>7} {r['cores_busy']:>5.2f} {r['wall_s']:>6.1f}"
            + (f"  {r['error']}" if r["error"] else ""),
            flush=True,
        )
    clean = [r for r in rows if r["exit"] == 0 and r["outcome"] == "success"]
    touched = [r for r in rows if r["contact"]]
    print(
        f"result: {a.scenario.stem} realtime launches (seeds {a.seeds}): {len(clean)} of "
        f"{len(rows)} clean (every goal, no contact, never inside rho0), {len(touched)} with a "
        f"contact (target: all clean); recordings in {a.out}"
    )
    (a.out / "series.json").write_text(json.dumps(rows, indent=1))
    return 0 if len(clean) == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
