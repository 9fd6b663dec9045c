"""`tidelink launch`: a Zenoh router and every service as its own OS process, supervised.

Bring-up: the router (`tidelink router`) listens on an explicit endpoint (by default 7447 on
loopback, where the watchers look, when free: router.py); the launcher joins
it as a client, records everything, and starts the local services as clients; remote ones
join with `tidelink service`. The mission clock starts only once every service has declared
its liveliness token. At the end (the mission's end, max_time or Ctrl-C) the services and
then the router are stopped (SIGINT, SIGTERM, SIGKILL per process group), and the run's
metrics (metrics.json) and plot (run.png) are written beside the per-service logs.
"""

from __future__ import annotations

import fnmatch
import json
import time
from collections.abc import Callable, Sequence
from contextlib import AbstractContextManager, ExitStack
from dataclasses import dataclass, field
from pathlib import Path

import msgspec

from common.config.bus import DEFAULT_CONNECT, BusConfig
from common.config.scenario import Scenario
from common.jsonsafe import JsonObject
from common.runtime.distributed import lockstep, realtime_driver
from common.runtime.distributed.acl import access_control, run_grants
from common.runtime.distributed.bringup import (
    END_LINGER_S,
    RELEASE_S,
    ClockSide,
    clock_bus,
    run_keys,
)
from common.runtime.distributed.lockstep import Coordinator
from common.runtime.distributed.observer import Driver, RunContext
from common.runtime.distributed.realtime_driver import RealtimeDriver
from common.runtime.metrics_record import RunMetrics
from common.runtime.model.dataflow import FLEET_SEP
from common.runtime.model.mission import Mission, load_mission, preload
from common.runtime.model.result import RunResult
from common.runtime.model.silence import thresholds
from common.runtime.processes.forkserver import warm_up
from common.runtime.processes.policy import RestartPolicy
from common.runtime.processes.signals import Interrupted, StopRequest, stop_on_signals
from common.runtime.processes.supervisor import ServiceFailed, Supervisor
from services.launcher.outputs import save_run
from services.launcher.progress import Display, LoggedDisplay, MissionView, ProgressObserver
from services.launcher.router import ROUTER, Listening, start_router

SERVICE_MODULES = {
    "realtime": realtime_driver.SERVICE_MODULE,
    "lockstep": lockstep.SERVICE_MODULE,
}


# An in-process watcher of the run (e.g. services/recording's TapRecorder): entered with the
# clock's bus, before any service starts, so it misses nothing; left before launch returns.
Attach = Callable[[ClockSide], AbstractContextManager[object]]


def select_services(names: tuple[str, ...], wanted: tuple[str, ...]) -> tuple[str, ...]:
    """The services `wanted` names: exact names or glob patterns ("auv2.*"; "auv2/*" and
    "auv2/planner" spell a fleet vehicle's services too), in dataflow order. ValueError for an
    item that names no service (a typo would leave a service unstarted, the run waiting)."""
    out: set[str] = set()
    for item in wanted:
        pattern = item.replace("/", FLEET_SEP)
        hit = [n for n in names if fnmatch.fnmatchcase(n, pattern)]
        if not hit:
            raise ValueError(
                f"--only: {item!r} names no service; this mission has {', '.join(names)}"
            )
        out.update(hit)
    return tuple(n for n in names if n in out)


@dataclass(frozen=True, kw_only=True)
class LaunchOptions:
    """How to launch: which services here, where the router listens, restart policies, and
    what to attach to the clock's side of the bus."""

    only: tuple[str, ...] | None = None  # services started here (None: all of them)
    listen: tuple[str, ...] = ()  # router endpoints (default: 7447 on loopback if free)
    policies: dict[str, RestartPolicy] = field(default_factory=dict)  # default: never
    plot: bool = True
    grace_s: float = 3.0  # per stop signal (SIGINT, then SIGTERM) before the next one
    attach: tuple[Attach, ...] = ()


@dataclass
class LaunchOutcome:
    """What a launch produced: its result, the metrics written and where everything is."""

    result: RunResult
    metrics: RunMetrics[msgspec.Struct]
    out: Path
    plot: Path | None
    unwritten: list[str] = field(default_factory=list)  # outputs that could not be written


def launch(
    scenario: Scenario, raw: JsonObject, out: Path, opts: LaunchOptions, display: Display
) -> LaunchOutcome:
    """Run one mission across processes; see the module docstring. Raises ServiceFailed
    (naming the service) when a service fails for good, Interrupted if stopped before the
    services came up."""
    kind = scenario.runtime.kind
    if kind not in SERVICE_MODULES:
        raise ValueError(f"runtime.kind: launch runs 'realtime' or 'lockstep', not {kind!r}")
    mission = load_mission(scenario)
    names = mission.dataflow.names
    local = names if opts.only is None else select_services(names, opts.only)
    out.mkdir(parents=True, exist_ok=True)
    scenario_json = out / "scenario.json"
    scenario_json.write_text(json.dumps(raw, indent=1))
    display = LoggedDisplay(display, out / "logs" / "launch.log")
    # the services are forked from a fork server that has imported them once (started now,
    # beside the router): a launch's services, and a restarted one, start in milliseconds
    if local:
        warm_up(preload(mission))
    sup = Supervisor(out / "logs", pid_file=out / "pids.json", forked=True)
    bus = scenario.bus
    acl_file = None
    if bus.secured:
        acl_file = out / "acl.json"  # kept beside the logs, for review
        acl_file.write_text(
            json.dumps(access_control(run_grants(mission.dataflow, run_keys(scenario))), indent=1)
        )
    wall0 = time.monotonic()
    with stop_on_signals() as stop:
        try:
            listening = start_router(
                sup,
                opts.listen,
                timeout_s=scenario.runtime.start_timeout_s,
                cancelled=lambda: stop.requested,
                certs=bus.certs if bus.secured else None,
                acl=acl_file,
                policy=opts.policies.get(ROUTER),
            )
            endpoint = listening.endpoint
            _say_where(display, bus, opts.listen, listening)
            certs = f" --certs {bus.certs}" if bus.secured else ""
            remote = [n for n in names if n not in local]
            if remote:
                where = (opts.listen[0] if opts.listen else endpoint).replace(
                    "0.0.0.0", "<this host>"
                )
                lockstep = " --runtime lockstep" if kind == "lockstep" else ""
                display.event(
                    f"waiting for {', '.join(remote)} to join: on their hosts run `tidelink "
                    f"service NAME SCENARIO --connect {where}{lockstep}{certs}` with the same "
                    "--set, --seed and --time-scale"
                )
            result = _run(
                scenario, mission, local, endpoint, scenario_json, opts, sup, display, stop
            )
        finally:
            grace = 0.5 if stop.hurry else opts.grace_s
            sup.stop_in_order([n for n in sup.names() if n != ROUTER], [ROUTER], grace_s=grace)
            display.close()
    saved = save_run(result, scenario, out, wall_s=time.monotonic() - wall0, plot=opts.plot)
    return LaunchOutcome(
        result=result,
        metrics=saved.metrics,
        out=out,
        plot=saved.plot,
        unwritten=saved.unwritten,
    )


def _say_where(
    display: Display, bus: BusConfig, listen: tuple[str, ...], listening: Listening
) -> None:
    """Where the router listens and how to watch the run: with no flags at all when it is
    where the watchers look by default."""
    shown = bus.endpoint(listening.endpoint)
    where = ", ".join(bus.endpoint(e) for e in listen) or shown
    if listening.instead_of_default is not None:
        where += f" ({listening.instead_of_default}, so the watchers need --connect)"
    display.event(
        f"router listening on {where}"
        + (" (mutual TLS, access control from the dataflow)" if bus.secured else "")
    )
    certs = f" --certs {bus.certs}" if bus.secured else ""
    connect = "" if listening.endpoint == DEFAULT_CONNECT else f" --connect {shown}"
    watch = f"tidelink monitor{connect}{certs} (or tidelink foxglove{connect}{certs})"
    hosts = "" if listen else "; for other hosts, launch with --listen tcp/0.0.0.0:PORT"
    display.event(f"watch it live from another terminal: {watch}{hosts}")


def _run(
    scenario: Scenario,
    mission: Mission,
    local: tuple[str, ...],
    endpoint: str,
    scenario_json: Path,
    opts: LaunchOptions,
    sup: Supervisor,
    display: Display,
    stop: StopRequest,
) -> RunResult:
    """Join the router, start the local services, run the mission in its runtime."""
    kind = scenario.runtime.kind
    keys = run_keys(scenario)
    view = MissionView(scenario)
    limits = thresholds(mission.dataflow, scenario.runtime.stats_period_s)
    observer = ProgressObserver(view, display, limits)
    cfg = scenario.bus.client_of(endpoint)
    raw = json.loads(scenario_json.read_text())
    lockstep = kind == "lockstep"
    with (
        clock_bus(cfg, keys, mission.dataflow, raw, lockstep=lockstep) as side,
        ExitStack() as attached,
    ):
        for hook in opts.attach:
            attached.enter_context(hook(side))
        for name in local:
            argv = [name, "--scenario-json", str(scenario_json), "--connect", endpoint]
            # a restarted lockstep service would lose its state and the run its determinism
            policy = opts.policies.get(name) if kind == "realtime" else None
            sup.start(name, ["-m", SERVICE_MODULES[kind], *argv], policy)
        ctx = RunContext(
            scenario=scenario, mission=mission, keys=keys, sup=sup, observer=observer, stop=stop
        )
        if kind == "lockstep":
            coord = Coordinator(ctx)
            try:
                result = _until_interrupted(coord, side, view)
                side.announce_end(result)
                return result
            finally:
                side.bus.close()  # our clock token goes: lockstep services are released
                sup.wait_exited(_joined(local, coord.alive), RELEASE_S)
        driver = RealtimeDriver(ctx)
        result = _until_interrupted(driver, side, view)
        side.announce_end(result)
        # the services leave on the stop Tick, the clock's session still open (END_LINGER_S)
        joined = _joined(local, driver.alive)
        left = sup.wait_exited(joined, END_LINGER_S)
    # one that missed the stop Tick leaves when the clock's token has gone CLOCK_GRACE_S
    if not left:
        sup.wait_exited(joined, RELEASE_S)
    return result


def _joined(local: Sequence[str], alive: set[str]) -> list[str]:
    """The local services that joined the run: only they hear its end and leave by
    themselves (one still starting when a launch is interrupted is stopped at once, instead
    of after RELEASE_S of waiting for nothing)."""
    return [n for n in local if n in alive]


def _until_interrupted(driver: Driver, side: ClockSide, view: MissionView) -> RunResult:
    """Wait for the services and drive the run; a stop request ends it as 'interrupted'."""
    try:
        driver.await_alive(side.inbox)
        return driver.drive(side.inbox, side.ticks, side.tap)
    except Interrupted:
        driver.observer.event(f"mission ended at t={view.t_sim:.2f} s: interrupted")
        metrics = driver.mission.metrics(driver.record)
        return RunResult("interrupted", view.t_sim, 0, driver.record, metrics)
    except ServiceFailed as exc:
        # what the run measured until then is still its result: metrics.json is written
        driver.observer.event(f"mission failed at t={view.t_sim:.2f} s: {exc}")
        metrics = driver.mission.metrics(driver.record)
        return RunResult("service_failed", view.t_sim, 0, driver.record, metrics, failure=str(exc))
