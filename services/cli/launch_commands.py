"""The deployment sub-commands: `launch` (router + supervised services) and `service` (one
service joining a run from any host)."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from common.config.bus import DEFAULT_CONNECT
from common.jsonsafe import JsonObject
from services.cli.core_commands import (
    check_exposure,
    report_outcome,
    runtime_overrides,
    scenario_check,
)
from services.cli.flags import (
    Subparsers,
    certs_args,
    command,
    connect_arg,
    host_args,
    listen_arg,
    no_plot_arg,
    positive,
    report_args,
    scenario_args,
)

if TYPE_CHECKING:
    from common.config.bus import BusConfig
    from common.config.scenario import Scenario
    from common.runtime.distributed.bringup import ClockSide
    from common.runtime.processes.policy import RestartPolicy
    from services.launcher.launch import LaunchOutcome
    from services.recording.tap_recorder import TapRecorder

RESTART_HELP = (
    "restart policy [NAME=]MODE[:MAX], MODE one of never, on-failure, always (default never); "
    "without NAME= for every service (never the router: only router=MODE restarts it); "
    "repeatable, e.g. --restart filter=on-failure:5"
)


def cmd_launch(a: argparse.Namespace) -> int:
    """start a router and every service as supervised processes"""
    from common.config.scenario import load_scenario
    from common.runtime.model.mission import load_mission
    from common.runtime.processes.signals import Interrupted
    from services.cli.summary import print_run_end
    from services.launcher.launch import LaunchOptions, launch
    from services.launcher.progress import make_display

    scenario, raw = load_scenario(a.scenario, runtime_overrides(a), a.seed, check=scenario_check(a))
    names = load_mission(scenario).dataflow.names
    only = None if a.only is None else tuple(n for n in a.only.split(",") if n.strip())
    _check_launch(a, scenario, names, only)
    out = a.out or Path("runs") / f"{scenario.run.name}-launch-s{scenario.run.seed}"
    recorders: list[TapRecorder] = []
    opts = LaunchOptions(
        only=only,
        listen=tuple(a.listen),
        plot=not a.no_plot,
        policies=_restart_policies(a, names),
        attach=(_recorder(scenario, raw, out, recorders),) if a.record else (),
    )
    try:
        outcome = launch(
            scenario, raw, out, opts, make_display(sys.stderr, every_s=a.progress_every)
        )
    except Interrupted:
        print("tidelink: interrupted before the mission started", file=sys.stderr)
        return 130
    print_run_end(
        outcome,
        out,
        json_output=a.json,
        all_metrics=a.all_metrics,
        more=[("logs", out / "logs")],
        notes=[_recorded(r) for r in recorders],
    )
    return _launch_exit(outcome, json_output=a.json)


def _check_launch(
    a: argparse.Namespace, scenario: Scenario, names: tuple[str, ...], only: tuple[str, ...] | None
) -> None:
    """What a launch is refused for before any process starts: a listener beyond this
    machine without --certs or --insecure, an endpoint the bus cannot serve, an identity
    without its certificate, --restart in lockstep."""
    from common.config.errors import ConfigValueError
    from common.runtime.distributed.acl import LAUNCHER, ROUTER
    from services.launcher.launch import select_services

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


def _restart_policies(a: argparse.Namespace, names: tuple[str, ...]) -> dict[str, RestartPolicy]:
    """Each service's restart policy: --restart's, else never with --backoff's delays."""
    from common.runtime.distributed.acl import ROUTER
    from common.runtime.processes.policy import RestartPolicy, policies_for

    default = RestartPolicy(backoff_s=a.backoff, backoff_max_s=max(a.backoff, 30.0))
    return policies_for(names, a.restart, default, named_only=(ROUTER,))


def _recorder(
    scenario: Scenario, raw: JsonObject, out: Path, recorders: list[TapRecorder]
) -> Callable[[ClockSide], TapRecorder]:
    """--record: what the launch attaches to its clock side, a recorder of every frame to
    out/run.mcap, kept in `recorders` to report on at the end."""

    def record(side: ClockSide) -> TapRecorder:
        from services.cli.record_commands import foxglove_view
        from services.recording.tap_recorder import TapRecorder

        recorders.append(TapRecorder(side, out / "run.mcap", raw, view=foxglove_view(scenario)))
        return recorders[-1]

    return record


def _recorded(r: TapRecorder) -> str:
    """The line that says what a --record recorder wrote."""
    return (
        f"recording: {r.path} ({r.writer.frames} frames, {r.path.stat().st_size / 1024:.1f} KiB)"
        + ("" if r.error is None else f"; writing failed: {r.error}")
        + (f"; {r.writer.lost} frames after that not written" if r.writer.lost else "")
    )


def _launch_exit(outcome: LaunchOutcome, *, json_output: bool) -> int:
    """A launch's exit status: 1 when a service failed for good, 130 interrupted, else the
    mission's (report_outcome); a failure the run went on without is said on stderr."""
    if outcome.result.failure and outcome.result.reason == "service_failed":
        # the metrics of the run until then are written; the failure is the exit status
        print(f"tidelink: error: {outcome.result.failure}", file=sys.stderr)
        return 1
    if outcome.result.failure:  # a fleet went on without what it lost: its outcome says how
        print(f"tidelink: {outcome.result.failure}", file=sys.stderr)
    if outcome.result.reason == "interrupted":
        return 130
    return report_outcome(outcome.metrics, json_output=json_output)


def cmd_service(a: argparse.Namespace) -> int:
    """run one service of a launched mission (any host)"""
    from common.config.scenario import load_scenario
    from common.runtime.distributed.lockstep_service import LockstepService
    from common.runtime.distributed.realtime_service import RealtimeService
    from common.runtime.distributed.service_process import ServiceSetup
    from common.runtime.processes.children import wait_for_endpoint
    from common.runtime.processes.signals import Shutdown, install_shutdown_handlers

    scenario, raw = load_scenario(a.scenario, runtime_overrides(a), a.seed)
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


def register(sub: Subparsers) -> None:
    """Add launch and service to the tidelink parser."""
    la = command(sub, "launch", cmd_launch)
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
    la.add_argument(
        "--progress-every",
        type=positive("number of seconds"),
        default=2.0,
        metavar="SECONDS",
        help="wall seconds between progress lines when stderr is not a terminal (default 2; "
        "`tidelink chaos` strikes a fault at the first line past its time)",
    )
    no_plot_arg(la)
    la.add_argument(
        "--record",
        action="store_true",
        help="record the run, every frame, to DIR/run.mcap (MCAP; `tidelink replay`, "
        "`tidelink metrics`, Foxglove)",
    )
    report_args(la)
    host_args(la)

    sv = command(sub, "service", cmd_service)
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


def _runtime_args(p: argparse.ArgumentParser, *, runtime_help: str, time_scale_help: str) -> None:
    """--runtime (realtime or lockstep: the distributed ones) and --time-scale, which a
    launch and each of its services must be given alike."""
    p.add_argument(
        "--runtime", choices=("realtime", "lockstep"), default="realtime", help=runtime_help
    )
    p.add_argument("--time-scale", type=float, default=None, help=time_scale_help)
