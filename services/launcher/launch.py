"""`tidelink launch`: a Zenoh router and every service as its own OS process, supervised.

Bring-up: the router (`tidelink router`) listens on an explicit endpoint; the launcher joins
it as a client, records everything, and starts the local services as clients; remote ones
join with `tidelink service`. The mission clock starts only once every service has declared
its liveliness token. At the end (the mission's end, max_time or Ctrl-C) the services and
then the router are stopped (SIGINT, SIGTERM, SIGKILL per process group), and the run's
metrics (metrics.json) and plot (run.png) are written beside the per-service logs.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.bus import Bus, Inbox, Keys
from common.config.bus import BusConfig
from common.config.scenario import Scenario
from common.runtime.inproc import RunResult
from common.runtime.mission import load_mission
from common.runtime.run import write_outputs
from common.runtime.service_process import CLOCK
from common.runtime.ticks import TickSender
from services.launcher.interrupt import Interrupted, StopRequest, stop_on_signals
from services.launcher.lockstep_drive import LockstepDriver
from services.launcher.plot import plot_run
from services.launcher.policy import RestartPolicy
from services.launcher.progress import Display, LoggedDisplay, MissionView
from services.launcher.realtime_drive import RealtimeDriver
from services.launcher.router import ROUTER, start_router
from services.launcher.supervise import Supervisor

SERVICE_MODULES = {
    "realtime": "common.runtime.realtime_service",
    "lockstep": "common.runtime.lockstep_service",
}
RELEASE_S = 10.0  # for services to leave by themselves at the end, before any signal


@dataclass(frozen=True, kw_only=True)
class LaunchOptions:
    """How to launch: which services here, where the router listens, restart policies."""

    only: tuple[str, ...] | None = None  # services started here (None: all of them)
    listen: tuple[str, ...] = ()  # router endpoints (default: a free loopback port)
    policies: dict[str, RestartPolicy] = field(default_factory=dict)  # default: never
    plot: bool = True
    grace_s: float = 3.0  # per stop signal (SIGINT, then SIGTERM) before the next one


@dataclass
class LaunchOutcome:
    """What a launch produced: its result, the metrics written and where everything is."""

    result: RunResult
    metrics: dict[str, Any]
    out: Path
    plot: Path | None


def launch(
    scenario: Scenario, raw: dict[str, Any], out: Path, opts: LaunchOptions, display: Display
) -> LaunchOutcome:
    """Run one mission across processes; see the module docstring. Raises ServiceFailed
    (naming the service) when a service fails for good, Interrupted if stopped before the
    services came up."""
    kind = scenario.runtime.kind
    if kind not in SERVICE_MODULES:
        raise ValueError(f"runtime.kind: launch runs 'realtime' or 'lockstep', not {kind!r}")
    names = load_mission(scenario).names
    local = names if opts.only is None else opts.only
    unknown = sorted(set(local) - set(names))
    if unknown:
        raise ValueError(
            f"--only: unknown service(s) {', '.join(unknown)}; this mission has {', '.join(names)}"
        )
    out.mkdir(parents=True, exist_ok=True)
    scenario_json = out / "scenario.json"
    scenario_json.write_text(json.dumps(raw, indent=1))
    display = LoggedDisplay(display, out / "logs" / "launch.log")
    sup = Supervisor(out / "logs", pid_file=out / "pids.json")
    wall0 = time.monotonic()
    with stop_on_signals() as stop:
        try:
            endpoint = start_router(
                sup,
                opts.listen,
                timeout_s=scenario.runtime.start_timeout_s,
                cancelled=lambda: stop.requested,
            )
            display.event(f"router listening on {', '.join(opts.listen) or endpoint}")
            remote = [n for n in names if n not in local]
            if remote:
                where = (opts.listen[0] if opts.listen else endpoint).replace(
                    "0.0.0.0", "<this host>"
                )
                lockstep = " --runtime lockstep" if kind == "lockstep" else ""
                display.event(
                    f"waiting for {', '.join(remote)} to join: on their hosts run `tidelink "
                    f"service NAME SCENARIO --connect {where}{lockstep}` with the same --set, "
                    "--seed and --time-scale"
                )
            result = _run(scenario, raw, local, endpoint, scenario_json, opts, sup, display, stop)
        finally:
            grace = 0.5 if stop.hurry else opts.grace_s
            sup.stop_in_order([n for n in sup.names() if n != ROUTER], [ROUTER], grace_s=grace)
            display.close()
    metrics = write_outputs(result, scenario, out, wall_s=time.monotonic() - wall0)
    plot = None
    if opts.plot:
        plot = plot_run(
            result.record,
            scenario,
            out / "run.png",
            title=f"{scenario.run.name} (seed {scenario.run.seed}, "
            f"{scenario.controller.kind}, {kind}): {result.reason} at "
            f"t={result.t_end:.1f} s",
        )
    return LaunchOutcome(result=result, metrics=metrics, out=out, plot=plot)


def _run(
    scenario: Scenario,
    raw: dict[str, Any],
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
    keys = Keys(scenario.run.name, scenario.run.vehicle)
    view = MissionView(scenario)
    with Bus(BusConfig(mode="client", connect=(endpoint,)), keys) as bus:
        inbox = Inbox()
        bus.subscribe(keys.all_streams, inbox)
        bus.watch_alive(inbox)
        tick_pub = TickSender(bus, load_mission(scenario).names)
        bus.declare_alive(CLOCK)
        for name in local:
            args = ["-m", SERVICE_MODULES[kind], name, "--scenario-json", str(scenario_json)]
            policy = opts.policies.get(name) if kind == "realtime" else None
            sup.start(name, [*args, "--connect", endpoint], policy)
        if kind == "lockstep":
            driver = LockstepDriver(scenario, raw, sup.log_dir, view, display, stop)
            driver.children = sup.children  # a dead service or router fails the run at once
            try:
                return _lockstep(driver, inbox, tick_pub, view, display)
            finally:
                bus.close()  # our clock token goes: lockstep services are released and leave
                sup.wait_exited(list(local), RELEASE_S)
        rt = RealtimeDriver(scenario, load_mission(scenario), keys, sup, view, display, stop)
        try:
            rt.await_alive(inbox)
        except Interrupted:
            return RunResult("interrupted", 0.0, 0, rt.record, rt.mission.metrics(rt.record))
        result = rt.drive(inbox, tick_pub)
    # the services leave on the stop Tick: let them close their sessions before any signal
    sup.wait_exited(list(local), RELEASE_S)
    return result


def _lockstep(
    driver: LockstepDriver,
    inbox: Inbox,
    tick_pub: TickSender,
    view: MissionView,
    display: Display,
) -> RunResult:
    try:
        driver.await_alive(inbox)
        display.event("mission clock started (lockstep: virtual time)")
        result = driver.drive(inbox, tick_pub)
    except Interrupted:
        display.event(f"mission ended at t={view.t_sim:.2f} s: interrupted")
        metrics = driver.mission.metrics(driver.record)
        return RunResult("interrupted", view.t_sim, 0, driver.record, metrics)
    display.event(f"mission ended at t={result.t_end:.2f} s: {result.reason}")
    return result
