"""The core sub-commands: check, run, router."""

from __future__ import annotations

import argparse
import contextlib
import functools
import json
import logging
import os
import sys
import threading
import time
from pathlib import Path
from typing import TYPE_CHECKING, Any

from common.jsonsafe import JsonObject
from services.cli.flags import (
    Subparsers,
    budget_arg,
    certs_args,
    command,
    connect_arg,
    host_args,
    insecure_arg,
    listen_arg,
    no_plot_arg,
    report_args,
    scenario_args,
)

if TYPE_CHECKING:
    from common.config.scenario import ScenarioCheck
    from common.runtime.metrics_record import RunMetrics
    from services.launcher.plot_worker import PlotWorker

log = logging.getLogger("tidelink")


ROUTER_CLOSE_S = 3.0  # how long `tidelink router` gives its session to close on a signal
# `run` and `launch`: the mission ran to its end (metrics written) without success: contact
# with an obstacle, the goal not reached, or the goal reached inside the safety distance rho0
# (services/mission/outcome.py). Distinct from 1 (a service or the run failed).
EXIT_MISSION_FAILED = 3


def certs_overrides(certs: str | None) -> list[str]:
    """The scenario overrides --certs stands for, so every process of the run gets them."""
    if certs is None:
        return []
    return ['bus.security="mtls"', f"bus.certs={json.dumps(certs)}"]


def runtime_overrides(a: argparse.Namespace) -> list[str]:
    """The scenario overrides of a command that runs one: its --set, and what --certs,
    --runtime (unless None: the scenario's) and --time-scale stand for."""
    overrides = list(a.overrides) + certs_overrides(a.certs)
    if a.runtime:
        overrides.append(f'runtime.kind="{a.runtime}"')
    if a.time_scale is not None:
        overrides.append(f"runtime.time_scale={a.time_scale}")
    return overrides


def check_exposure(listen: list[str] | tuple[str, ...], secured: bool, insecure: bool) -> None:
    """Refuse to listen beyond this machine without mTLS unless --insecure says so (then
    warn): an open router lets anyone who reaches it command the vehicle."""
    from common.config.bus import is_loopback
    from common.config.errors import ConfigError

    exposed = [ep for ep in listen if not is_loopback(ep)]
    if not exposed or secured:
        return
    if not insecure:
        raise ConfigError(
            "",
            "--listen",
            f"{', '.join(exposed)} is reachable from other machines: give --certs DIR "
            "(mutual TLS and access control; `tidelink certs DIR` makes them) or, on a "
            "network you trust, --insecure",
        )
    print(
        f"tidelink: WARNING: listening on {', '.join(exposed)} without TLS or access control "
        "(--insecure): anyone who reaches it can command the vehicle",
        file=sys.stderr,
    )


def scenario_check(a: argparse.Namespace) -> ScenarioCheck:
    """The check a command that runs a scenario applies: geometry and the --budget'ed work."""
    from common.config.budget import DEFAULT_BUDGET
    from common.world.check import check_scenario

    return functools.partial(check_scenario, budget=DEFAULT_BUDGET.scaled(a.budget))


def cmd_check(a: argparse.Namespace) -> int:
    """validate a scenario file and exit non-zero on any problem"""
    from common.config.scenario import load_scenario
    from common.config.work import estimate
    from common.runtime.model.mission import load_mission

    scenario, _ = load_scenario(a.scenario, a.overrides, a.seed, check=scenario_check(a))
    names = ", ".join(load_mission(scenario).dataflow.names)
    print(f"{a.scenario}: OK (mission {scenario.run.mission_name}, services {names})")
    print(f"  estimated: {estimate(scenario).summary()}")
    return 0


def cmd_run(a: argparse.Namespace) -> int:
    """run one mission and write DIR/metrics.json and DIR/run.png"""
    from services.launcher.plot_worker import PlotWorker

    # first: the worker imports matplotlib on the other core while we load and run
    with PlotWorker() if not a.no_plot else contextlib.nullcontext() as worker:
        return _run(a, worker)


def _run(a: argparse.Namespace, worker: PlotWorker | None) -> int:
    """cmd_run's work, the plot drawn by `worker` (None: no plot)."""
    from common.config.scenario import load_scenario
    from common.runtime.run import run_scenario
    from services.cli.summary import print_run_end
    from services.launcher.outputs import save_run

    scenario, raw = load_scenario(a.scenario, runtime_overrides(a), a.seed, check=scenario_check(a))
    if scenario.runtime.kind != "inproc":  # the process is the run's router
        check_exposure(scenario.bus.listen, scenario.bus.secured, a.insecure)
    out = (
        a.out or Path("runs") / f"{scenario.run.name}-{scenario.runtime.kind}-s{scenario.run.seed}"
    )
    wall0 = time.monotonic()
    result = run_scenario(scenario, raw, log_dir=out / "logs")
    wall_s = time.monotonic() - wall0
    saved = save_run(result, scenario, out, wall_s=wall_s, plot=worker is not None, worker=worker)
    print_run_end(saved, out, json_output=a.json, all_metrics=a.all_metrics)
    return report_outcome(saved.metrics, json_output=a.json)


def report_outcome(metrics: RunMetrics[Any], *, json_output: bool) -> int:
    """Say the run's outcome in words (a failure in the summary on stdout, on stderr when
    stdout is JSON; a success in the summary only) and return the exit code:
    EXIT_MISSION_FAILED for a failure, else 0."""
    from services.mission.verdict import fell_behind, verdict

    behind = fell_behind(metrics)
    if behind is not None:
        print(f"tidelink: note: {behind}", file=sys.stderr, flush=True)
    judged = verdict(metrics)
    if judged is None:
        return 0
    succeeded, words = judged
    if succeeded:
        if not json_output:
            print(f"mission succeeded: {words}", flush=True)
        return 0
    print(f"mission failed: {words}", file=sys.stderr if json_output else sys.stdout, flush=True)
    return EXIT_MISSION_FAILED


def cmd_router(a: argparse.Namespace) -> int:
    """run a Zenoh router (no zenohd is installable here)"""
    from common.bus import Bus, Keys
    from common.config.bus import BusConfig
    from common.config.errors import ConfigError
    from common.runtime.processes.signals import (
        Shutdown,
        install_shutdown_handlers,
        wait_for_stop,
    )

    check_exposure(a.listen, a.certs is not None, a.insecure)
    acl = None if a.acl is None else _read_acl(a.acl)
    if acl is not None and a.certs is None:
        raise ConfigError(str(a.acl), "", "--acl needs --certs (rules name certificate identities)")
    cfg = BusConfig(
        mode="router",
        listen=tuple(a.listen),
        connect=tuple(a.connect),
        security="mtls" if a.certs else "none",
        certs=a.certs or "",
    )
    install_shutdown_handlers()
    bus = Bus(cfg, Keys("router", "router"), identity=a.identity, access_control=acl)
    with bus:
        try:
            where = ", ".join(cfg.endpoint(e) for e in a.listen)
            joined = "".join(f", joining {cfg.endpoint(e)}" for e in a.connect)
            print(f"zenoh router listening on {where}{joined}; Ctrl-C to stop", flush=True)
            wait_for_stop()  # the router works on Zenoh's threads; we only wait for a signal
        except Shutdown:
            # closing a router while its clients drop away (after a SIGKILLed launcher, say)
            # can take Zenoh many seconds; a router keeps nothing worth waiting for
            closing = threading.Thread(target=bus.close, daemon=True)
            closing.start()
            closing.join(ROUTER_CLOSE_S)
            if closing.is_alive():
                log.warning("the router's session did not close in %g s; exiting", ROUTER_CLOSE_S)
                os._exit(0)
    return 0


def _read_acl(path: Path) -> JsonObject:
    """An access_control object (`tidelink acl SCENARIO --json`); ConfigError naming the file."""
    from common.config.errors import ConfigError

    try:
        acl = json.loads(path.read_text())
    except RecursionError:
        raise ConfigError(
            str(path), "", "cannot read an access control: nested too deeply"
        ) from None
    except (OSError, ValueError) as exc:
        raise ConfigError(str(path), "", f"cannot read an access control: {exc}") from None
    if not isinstance(acl, dict) or "rules" not in acl:
        raise ConfigError(str(path), "", "not an access_control object (`tidelink acl --json`)")
    return acl


def register(sub: Subparsers) -> None:
    """Add check, run and router to the tidelink parser."""
    c = command(sub, "check", cmd_check)
    scenario_args(c)
    budget_arg(c)

    r = command(sub, "run", cmd_run)
    scenario_args(r)
    r.add_argument(
        "--runtime",
        choices=("inproc", "lockstep", "realtime"),
        default=None,
        help="override runtime.kind (default: the scenario's, else inproc)",
    )
    r.add_argument("--time-scale", type=float, default=None, help="realtime speed-up, e.g. 5")
    r.add_argument("--out", type=Path, default=None, help="output folder (default runs/<name>-...)")
    report_args(r)
    no_plot_arg(r)
    host_args(r)

    z = command(sub, "router", cmd_router)
    listen_arg(z, required=True, repeat=True, help="e.g. tcp/127.0.0.1:7447 (repeatable)")
    connect_arg(
        z,
        repeat=True,
        help="another router to join (repeatable; retried until it answers): one router per "
        "host of a fleet, each joined to the launch's",
    )
    certs_args(z, identity="router")
    z.add_argument(
        "--acl",
        type=Path,
        default=None,
        metavar="FILE",
        help="with --certs: enforce this access control (`tidelink acl SCENARIO --json`)",
    )
    insecure_arg(z)
