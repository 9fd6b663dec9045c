"""Where one tick's time goes: a mission inproc, per service core and phase.

One inproc run in this process (imports done before it), each core's step, deliver and
prepare timed (CPU time), the planner's command sequences counted apart; then the same run
under cProfile for its top functions. `--before DIR` runs the same measurement on another
checkout (DIR: its root, e.g. a `git archive` of an older commit) in a child process and
prints the two side by side. By default the default mission and the ocean (configs/ocean.toml:
its current field, ocean plant and navigation) are measured, a table each.

    python scripts/bench_profile.py [--before DIR] [--seed N] [--scenario TOML ...]
"""

from __future__ import annotations

import argparse
import cProfile
import importlib
import json
import os
import pstats
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = (ROOT / "configs" / "default.toml", ROOT / "configs" / "ocean.toml")
PHASES = ("step", "deliver", "prepare")


def _timed(acc: list[float], fn: Callable[..., Any]) -> Callable[..., Any]:
    def call(*args: Any, **kwargs: Any) -> Any:
        t0 = time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[0] += time.process_time() - t0

    return call


def measure(seed: int, scenario: Path = ROOT / "configs" / "default.toml") -> dict[str, Any]:
    """CPU seconds per core phase, in the command sequences and in the whole run; ticks and
    simulated seconds; the run's top functions by own time under cProfile."""
    import services.control.command.link as link
    from common.config.scenario import load_scenario
    from common.runtime.model import inproc

    # the cores' modules imported before the run: their import is not a tick's cost
    for name in ("estimator", "planner", "sensor", "vehicle", "tracker"):
        importlib.import_module(f"services.{name}.core")

    scn, _ = load_scenario(scenario, ['runtime.kind="inproc"'], seed)
    acc: dict[str, list[float]] = {}
    build = inproc.build_host

    def timed_host(*args: Any, **kwargs: Any) -> Any:
        host = build(*args, **kwargs)
        core = host.core
        for phase in PHASES:
            if hasattr(core, phase):
                key = f"{type(core).__name__.removesuffix('Core').lower()} {phase}"
                setattr(core, phase, _timed(acc.setdefault(key, [0.0]), getattr(core, phase)))
        return host

    sequence = link.command_sequence
    inproc.build_host = timed_host
    link.command_sequence = _timed(acc.setdefault("sequences", [0.0]), sequence)
    try:
        t0 = time.process_time()
        result = inproc.run_inproc(scn)
        total = time.process_time() - t0
    finally:
        inproc.build_host = build
        link.command_sequence = sequence
    prof = cProfile.Profile()
    prof.runcall(inproc.run_inproc, scn)
    stats = pstats.Stats(prof)
    entries: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    rows = sorted(entries.items(), key=lambda kv: -kv[1][2])[:8]
    top = [
        (f"{Path(f).name}:{line}({name})", own, cum, calls)
        for (f, line, name), (_, calls, own, cum, _) in rows
    ]
    return {
        "total_s": total,
        "ticks": result.ticks,
        "sim_s": result.t_end,
        "hash": result.metrics.trajectory_sha256,
        "phases": {k: v[0] for k, v in acc.items()},
        "top": top,
        "profiled_s": stats.total_tt,  # type: ignore[attr-defined]
        "scenario": scenario.stem,
    }


def table(runs: dict[str, dict[str, Any]]) -> None:
    """Print ms per tick per phase for each run (columns), and each run's top functions."""
    names = list(runs)
    first = runs[names[0]]
    print(
        f"{first.get('scenario', 'default')} mission inproc, seed {first['seed']}: "
        f"{first['sim_s']:.1f} s simulated, "
        f"{first['ticks']} ticks; CPU ms per tick (share of the run)"
    )
    print(f"{'':24s}" + "".join(f"{n:>22s}" for n in names))
    for r in runs.values():  # what no core took: the runtime's routing, the record, metrics
        r["phases"]["rest"] = r["total_s"] - sum(
            v for k, v in r["phases"].items() if k != "sequences"
        )
    keys = sorted(
        {k for r in runs.values() for k in r["phases"]} - {"rest", "sequences"},
        key=lambda k: -first["phases"].get(k, 0.0),
    )
    # the command sequences (in the planner's step and prepare) under the planner's phases
    after = max(i for i, k in enumerate(keys) if k in ("planner step", "planner prepare"))
    keys.insert(after + 1, "sequences")

    def cell(r: dict[str, Any], seconds: float) -> str:
        share = 100 * seconds / r["total_s"]
        return f"{1e3 * seconds / r['ticks']:8.3f} ({share:4.1f} %)".rjust(22)

    for k in keys:
        label = "  in command sequences" if k == "sequences" else k
        print(f"{label:24s}" + "".join(cell(r, r["phases"].get(k, 0.0)) for r in runs.values()))
    print(
        f"{'runtime, record, metrics':24s}"
        + "".join(cell(r, r["phases"]["rest"]) for r in runs.values())
    )
    print(f"{'whole run':24s}" + "".join(cell(r, r["total_s"]) for r in runs.values()))
    print(
        "trajectory_sha256: "
        + ", ".join(f"{n} {r['hash'][:12]}" for n, r in runs.items())
        + (" (the same)" if len({r["hash"] for r in runs.values()}) == 1 else " (DIFFERENT)")
    )
    here = runs[names[-1]]
    tick_ms = 1e3 * here["total_s"] / here["ticks"]
    seq_ms = 1e3 * here["phases"].get("sequences", 0.0) / here["ticks"]
    print(
        f"result: a tick of the {here.get('scenario', 'default')} mission inproc costs "
        f"{tick_ms:.2f} ms CPU, "
        f"{seq_ms:.2f} ms of it in the planner's command sequences"
        + (
            f" ({1e3 * first['total_s'] / first['ticks']:.2f} ms {names[0]})"
            if len(runs) > 1
            else ""
        )
    )
    for n, r in runs.items():
        print(
            f"{n}: top functions by own time under cProfile "
            f"(whole run {r['profiled_s']:.2f} s profiled)"
        )
        for where, own, cum, calls in r["top"][:5]:
            print(f"  {own:6.2f} s own {cum:6.2f} s cum {calls:8d} calls  {where}")


def main() -> None:
    ap = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--before", type=Path, help="root of another checkout to measure too")
    ap.add_argument("--label", default="before", help="--before's column heading")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument(
        "--scenario",
        type=Path,
        action="append",
        help="repeatable; default configs/default.toml and configs/ocean.toml",
    )
    ap.add_argument("--json", action="store_true", help="print this checkout's figures as JSON")
    a = ap.parse_args()
    scenarios = [p.resolve() for p in a.scenario or SCENARIOS]
    if a.json:
        print(json.dumps(dict(measure(a.seed, scenarios[0]), seed=a.seed)))
        return
    for k, scenario in enumerate(scenarios):
        if k:
            print()
        runs: dict[str, dict[str, Any]] = {}
        if a.before:
            cmd = [sys.executable, str(Path(__file__).resolve()), "--json", "--seed", str(a.seed)]
            out = subprocess.run(
                [*cmd, "--scenario", str(scenario)],
                cwd=a.before,
                env={**os.environ, "PYTHONPATH": str(a.before.resolve())},
                capture_output=True,
                text=True,
                check=True,
            ).stdout
            runs[a.label] = json.loads(out.splitlines()[-1])
        runs["this checkout"] = dict(measure(a.seed, scenario), seed=a.seed)
        table(runs)


if __name__ == "__main__":
    main()
