"""The deployment sub-commands: `launch` (router + supervised services) and `service` (one
service joining a run from any host)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from common.config.bus import DEFAULT_CONNECT
from services.cli.core_commands import (
    certs_overrides,
    check_exposure,
    report_outcome,
    scenario_check,
)
from services.cli.flags import (
    budget_arg,
    certs_args,
    connect_arg,
    details_arg,
    insecure_arg,
    listen_arg,
    no_plot_arg,
    scenario_args,
)

if TYPE_CHECKING:
    from common.config.bus import BusConfig
    from common.config.scenario import Scenario
    from common.runtime.distributed.bringup import ClockSide
    from services.recording.tap_recorder import TapRecorder

RESTART_HELP = (
    "restart policy [NAME=]MODE[:MAX], MODE one of never, on-failure, always (default never); "
    "without NAME= for every service (never the router: only router=MODE restarts it); "
    "repeatable, e.g. --restart filter=on-failure:5"
)


def _runtime_overrides(a: argparse.Namespace) -> list[str]:
    overrides = list(a.overrides) + certs_overrides(a.certs)
    overrides.append(f'runtime.kind="{a.runtime}"')
    if a.time_scale is not None:
        overrides.append(f"runtime.time_scale={a.time_scale}")
    return overrides


def cmd_launch(a: argparse.Namespace) -> int:
    from common.config.errors import ConfigValueError
    from common.config.scenario import load_scenario
    from common.runtime.distributed.acl import LAUNCHER, ROUTER
    from common.runtime.model.mission import load_mission
    from common.runtime.processes.policy import RestartPolicy, policies_for
    from common.runtime.processes.signals import Interrupted
    from services.launcher import LaunchOptions, launch
    from services.launcher.launch import select_services
    from services.launcher.progress import make_display

    scenario, raw = load_scenario(
        a.scenario, _runtime_overrides(a), a.seed, check=scenario_check(a)
    )
    names = load_mission(scenario).dataflow.names
    only = None if a.only is None else tuple(n for n in a.only.split(",") if n.strip())
    check_exposure(a.listen, scenario.bus.secured, a.insecure)
    scenario.bus.router_on(tuple(a.listen))  # e.g. a tls/ endpoint without --certs: say so now
    if scenario.bus.secured:  # every identity this host presents, before any process starts
        here = names if only is None else select_services(names, only)
        check_credentials(scenario.bus, [ROUTER, LAUNCHER, *here])
    if a.restart and scenario.runtime.kind == "lockstep":
        raise ConfigValueError(
            "--restart",
            "lockstep runs cannot restart a service (it would lose its state and the run "
            "its determinism); use --runtime realtime",
        )
    default = RestartPolicy(backoff_s=a.backoff, backoff_max_s=max(a.backoff, 30.0))
    out = a.out or Path("runs") / f"{scenario.run.name}-launch-s{scenario.run.seed}"
    recorders: list[TapRecorder] = []

    def record(side: ClockSide) -> TapRecorder:
        from services.cli.record_commands import foxglove_view
        from services.recording.tap_recorder import TapRecorder

        recorders.append(TapRecorder(side, out / "run.mcap", raw, view=foxglove_view(scenario)))
        return recorders[-1]

    opts = LaunchOptions(
        only=only,
        listen=tuple(a.listen),
        plot=not a.no_plot,
        policies=policies_for(names, a.restart, default, named_only=(ROUTER,)),
        attach=(record,) if a.record else (),
    )
    try:
        outcome = launch(scenario, raw, out, opts, make_display(sys.stderr))
    except Interrupted:
        print("tidelink: interrupted before the mission started", file=sys.stderr)
        return 130
    recorded = [
        f"recording: {r.path} ({r.writer.frames} frames, {r.path.stat().st_size / 1024:.1f} KiB)"
        + ("" if r.error is None else f"; writing failed: {r.error}")
        + (f"; {r.writer.lost} frames after that not written" if r.writer.lost else "")
        for r in recorders
    ]
    if a.json:
        print(json.dumps(outcome.metrics.to_json(), sort_keys=True, allow_nan=False))
        for line in recorded:
            print(line, file=sys.stderr)
    else:
        from services.cli.summary import print_summary

        written = not any("metrics.json" in w for w in outcome.unwritten)
        outputs = [("metrics", out / "metrics.json")] if written else []
        outputs += [("plot", outcome.plot)] if outcome.plot is not None else []
        outputs += [("logs", out / "logs")]
        print_summary(outcome.metrics, outputs, all_metrics=a.all_metrics)
        if not written:
            print("metrics: not written (see below)")
        for line in recorded:
            print(line)
    for why in outcome.unwritten:  # the outcome is still the run's: reported below, as ever
        print(f"tidelink: error: {why}", file=sys.stderr)
    if outcome.result.failure and outcome.result.reason == "service_failed":
        # the metrics of the run until then are written; the failure is the exit status
        print(f"tidelink: error: {outcome.result.failure}", file=sys.stderr)
        return 1
    if outcome.result.failure:  # a fleet went on without what it lost: its outcome says how
        print(f"tidelink: {outcome.result.failure}", file=sys.stderr)
    if outcome.result.reason == "interrupted":
        return 130
    return report_outcome(outcome.metrics, json_output=a.json)


def cmd_service(a: argparse.Namespace) -> int:
    from common.config.scenario import load_scenario
    from common.runtime.distributed.lockstep_service import LockstepService
    from common.runtime.distributed.realtime_service import RealtimeService
    from common.runtime.distributed.service_process import ServiceSetup
    from common.runtime.processes.children import wait_for_endpoint
    from common.runtime.processes.signals import Shutdown, install_shutdown_handlers

    scenario, raw = load_scenario(a.scenario, _runtime_overrides(a), a.seed)
    name = service_name(a.name, a.vehicle, scenario)
    if scenario.bus.secured:
        check_credentials(scenario.bus, [name])
    root = logging.getLogger()
    for h in root.handlers:
        h.setFormatter(logging.Formatter(f"%(asctime)s {name} %(levelname)s %(message)s"))
    if not a.verbose:
        root.setLevel(logging.INFO)
    install_shutdown_handlers()
    log = logging.getLogger("tidelink")
    timeout_s = scenario.runtime.start_timeout_s
    try:
        if not wait_for_endpoint(a.connect, 0.0):
            log.info("waiting up to %g s for the router at %s", timeout_s, a.connect)
            if not wait_for_endpoint(a.connect, timeout_s):
                raise TimeoutError(f"no router at {a.connect} after {timeout_s:g} s")
        setup = ServiceSetup.of(name, raw, a.connect)
        if a.runtime == "lockstep":
            return LockstepService(setup).run()
        return RealtimeService(setup).run()
    except Shutdown as exc:
        log.info("stopping on %s", exc)
        return 0


def service_name(name: str, vehicle: str | None, scenario: Scenario) -> str:
    """The service `tidelink service NAME [--vehicle ID]` runs, checked against the mission
    before any wait for the router: an unknown one is a config error naming those there are."""
    from common.config.errors import ConfigValueError
    from common.runtime.model.dataflow import qualified
    from common.runtime.model.mission import load_mission

    if vehicle is not None:
        ids = [v.id for v in scenario.vehicles]
        if vehicle not in ids:
            there = f"its vehicles are {', '.join(ids)}" if ids else "it has no [[vehicles]]"
            raise ConfigValueError("--vehicle", f"{vehicle!r} is not in this scenario: {there}")
        name = qualified(vehicle, name)
    names = load_mission(scenario).dataflow.names
    if name not in names:
        raise ConfigValueError("NAME", f"no service {name!r} in this mission: {', '.join(names)}")
    return name


def check_credentials(bus: BusConfig, identities: list[str]) -> None:
    """Validate each identity's certificate files (CredentialsError names the file: the CLI
    exits 2) before any process starts, rather than in a child's log."""
    from common.bus.certs import load_credentials

    for name in dict.fromkeys(n.strip() for n in identities if n.strip()):
        load_credentials(Path(bus.certs), name)


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add launch and service to the tidelink parser."""
    la = sub.add_parser("launch", help="start a router and every service as supervised processes")
    scenario_args(la)
    _runtime_args(
        la,
        runtime_help="realtime (default; wall clock, scaled) or lockstep (virtual time)",
        time_scale_help="realtime speed-up, e.g. 5 (default: the scenario's runtime.time_scale)",
    )
    la.add_argument(
        "--out", type=Path, default=None, help="run folder (default runs/<name>-launch-s<seed>)"
    )
    la.add_argument(
        "--only",
        default=None,
        metavar="NAME,...",
        help="start only these services here, by name or pattern (a fleet vehicle's: "
        "'auv2.*' or 'auv2/*'); the others join with `tidelink service` (--only '' starts "
        "none: router and clock only)",
    )
    listen_arg(
        la,
        repeat=True,
        help="router endpoint, e.g. tcp/0.0.0.0:7447 for other hosts (repeatable; default "
        f"{DEFAULT_CONNECT}, where the watchers look, or a free port on 127.0.0.1 when that "
        "one is taken)",
    )
    la.add_argument(
        "--restart", action="append", default=[], metavar="[NAME=]MODE[:MAX]", help=RESTART_HELP
    )
    la.add_argument(
        "--backoff",
        type=float,
        default=0.5,
        help="seconds before the first restart, doubled for each further one",
    )
    no_plot_arg(la)
    la.add_argument(
        "--record",
        action="store_true",
        help="record the run, every frame, to DIR/run.mcap (MCAP; `tidelink replay`, "
        "`tidelink metrics`, Foxglove)",
    )
    la.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    details_arg(la)
    budget_arg(la)
    certs_args(la, identity=None)
    insecure_arg(la)
    la.set_defaults(func=cmd_launch)

    sv = sub.add_parser("service", help="run one service of a launched mission (any host)")
    sv.add_argument("name", help="the service, e.g. planner (in a fleet: auv2.planner)")
    scenario_args(sv)
    sv.add_argument(
        "--vehicle",
        default=None,
        metavar="ID",
        help="in a fleet, the vehicle whose service this is: NAME planner --vehicle auv2 "
        "is auv2.planner",
    )
    connect_arg(sv, required=True, help="the launch's router, e.g. tcp/10.0.0.1:7447")
    _runtime_args(
        sv,
        runtime_help="as the launch was started (default realtime)",
        time_scale_help="as the launch was started (default: the scenario's)",
    )
    certs_args(sv, identity=None)
    sv.set_defaults(func=cmd_service)


def _runtime_args(p: argparse.ArgumentParser, *, runtime_help: str, time_scale_help: str) -> None:
    """--runtime (realtime or lockstep: the distributed ones) and --time-scale, which a
    launch and each of its services must be given alike."""
    p.add_argument(
        "--runtime", choices=("realtime", "lockstep"), default="realtime", help=runtime_help
    )
    p.add_argument("--time-scale", type=float, default=None, help=time_scale_help)
