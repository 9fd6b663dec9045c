"""The core sub-commands: check, run, router."""

from __future__ import annotations

import argparse
import json
import logging
import math
import signal
import time
from pathlib import Path
from typing import Any

log = logging.getLogger("tidelink")


DEFAULT_CONNECT = "tcp/127.0.0.1:7447"  # Zenoh's own default port, on this machine


def watcher_args(p: argparse.ArgumentParser, *, run_help: str, vehicle_help: str) -> None:
    """--connect, --run and --vehicle of the tools that watch live runs (monitor, foxglove,
    record): the run's router, and which run and vehicle to watch."""
    p.add_argument(
        "--connect",
        default=DEFAULT_CONNECT,
        metavar="ENDPOINT",
        help=f"the run's router (default {DEFAULT_CONNECT}; `tidelink launch` prints its own)",
    )
    p.add_argument("--run", default=None, help=run_help)
    p.add_argument("--vehicle", default=None, help=vehicle_help)


def scenario_args(p: argparse.ArgumentParser, *, required: bool = True) -> None:
    p.add_argument(
        "scenario",
        type=Path,
        nargs=None if required else "?",
        default=None,
        help="scenario TOML file, e.g. configs/default.toml",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, e.g. --set network.default.loss_p=0.2 (repeatable)",
    )
    p.add_argument("--seed", type=int, default=None, help="override run.seed")


def cmd_check(a: argparse.Namespace) -> int:
    from common.config.scenario import load_scenario
    from common.runtime.model.mission import load_mission
    from common.world.check import check_scenario

    scenario, _ = load_scenario(a.scenario, a.overrides, a.seed, check=check_scenario)
    names = ", ".join(load_mission(scenario).dataflow.names)
    print(f"{a.scenario}: OK (mission {scenario.run.mission}, services {names})")
    return 0


def cmd_run(a: argparse.Namespace) -> int:
    from common.config.scenario import load_scenario
    from common.runtime.run import run_scenario, write_outputs
    from common.world.check import check_scenario

    overrides = list(a.overrides)
    if a.runtime:
        overrides.append(f'runtime.kind="{a.runtime}"')
    if a.time_scale is not None:
        overrides.append(f"runtime.time_scale={a.time_scale}")
    scenario, raw = load_scenario(a.scenario, overrides, a.seed, check=check_scenario)
    out = (
        a.out or Path("runs") / f"{scenario.run.name}-{scenario.runtime.kind}-s{scenario.run.seed}"
    )
    wall0 = time.monotonic()
    result = run_scenario(scenario, raw, log_dir=out / "logs")
    metrics = write_outputs(result, scenario, out, wall_s=time.monotonic() - wall0)
    if a.json:
        print(json.dumps(metrics, sort_keys=True, allow_nan=False, default=_json_default))
    else:
        print_metrics(metrics, out)
    return 0


def _json_default(v: Any) -> Any:
    raise TypeError(f"not JSON: {v!r}")


def print_metrics(metrics: dict[str, Any], out: Path) -> None:
    """A readable table of the scalar metrics (the JSON file has everything)."""
    print_metrics_table(metrics)
    print(f"metrics: {out / 'metrics.json'}")


def print_metrics_table(metrics: dict[str, Any]) -> None:
    """The scalar metrics, one per line, sorted by name."""
    width = max(len(k) for k in metrics)
    for k, v in sorted(metrics.items()):
        if isinstance(v, dict | list):
            continue
        if isinstance(v, float):
            v = f"{v:.4g}" if math.isfinite(v) else str(v)
        print(f"  {k:<{width}}  {v}")


def cmd_router(a: argparse.Namespace) -> int:
    from common.bus import Bus, Keys
    from common.config.bus import BusConfig
    from common.runtime.processes.signals import Shutdown, install_shutdown_handlers

    install_shutdown_handlers()
    cfg = BusConfig(mode="router", listen=tuple(a.listen))
    try:
        with Bus(cfg, Keys("router", "router")):
            print(f"zenoh router listening on {', '.join(a.listen)}; Ctrl-C to stop", flush=True)
            while True:
                signal.pause()  # the router works on Zenoh's threads; we only wait for a signal
    except Shutdown:
        return 0


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add check, run and router to the tidelink parser."""
    c = sub.add_parser("check", help="validate a scenario file and exit non-zero on any problem")
    scenario_args(c)
    c.set_defaults(func=cmd_check)

    r = sub.add_parser("run", help="run one mission and write DIR/metrics.json")
    scenario_args(r)
    r.add_argument(
        "--runtime",
        choices=("inproc", "lockstep", "realtime"),
        default=None,
        help="override runtime.kind (default: the scenario's, else inproc)",
    )
    r.add_argument("--time-scale", type=float, default=None, help="realtime speed-up, e.g. 5")
    r.add_argument("--out", type=Path, default=None, help="output folder (default runs/<name>-...)")
    r.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    r.set_defaults(func=cmd_run)

    z = sub.add_parser("router", help="run a Zenoh router (no zenohd is installable here)")
    z.add_argument(
        "--listen",
        action="append",
        required=True,
        metavar="ENDPOINT",
        help="e.g. tcp/127.0.0.1:7447 (repeatable)",
    )
    z.set_defaults(func=cmd_router)
