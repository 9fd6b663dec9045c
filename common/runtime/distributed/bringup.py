"""Bring-up of a distributed run: the clock side's bus, and a run whose services are local.

`clock_bus` is what every driver of a run needs on the bus (the launcher's, and the one
`run_lockstep` / `run_realtime` start): a recording subscription to every stream of the run,
liveliness of its services, a tick sender, its own clock token, the declared dataflow
served as a queryable (Keys.dataflow) for any tool that joins, and the watch tap (the
monitoring copies, latest frames and scenario that watchers use, common/bus/tap.py).
`local_run` adds what `tidelink run` needs: this process is the Zenoh router, and the
services are forked here.
"""

from __future__ import annotations

import json
import logging
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

from common.bus import CLOCK, Bus, Inbox, Keys
from common.bus.tap import WatchTap
from common.config.bus import BusConfig
from common.config.scenario import Scenario
from common.jsonsafe import JsonObject
from common.runtime.distributed.acl import LAUNCHER, access_control, run_grants
from common.runtime.distributed.claim import claim
from common.runtime.distributed.observer import Driver, RunContext
from common.runtime.distributed.ticks import TickSender
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.mission import load_mission
from common.runtime.model.result import RunResult
from common.runtime.processes.children import connectable, free_port
from common.runtime.processes.forkserver import warm_up
from common.runtime.processes.supervisor import Supervisor

log = logging.getLogger("tidelink.run")

DATAFLOW_ENCODING = "application/json"
RELEASE_S = 10.0  # for services to leave by themselves at the end, before any signal
# at most, for realtime services to leave on the stop Tick while the clock's session is still
# open: closed at once, it could drop the RunEnd it had just queued for watchers
# (docs/notes/code-clock-session-lingers-for-run-end.md)
END_LINGER_S = 2.0
CATCH_UP_S = 2.0  # at most, for the watch tap to see the last frames the driver recorded


@dataclass
class ClockSide:
    """The driver's end of the bus: everything the run publishes arrives in `inbox`."""

    bus: Bus
    inbox: Inbox
    ticks: TickSender
    tap: WatchTap

    def announce_end(self, result: RunResult) -> None:
        """Tell watchers how the run ended (before the bus closes and the tokens go), once the
        tap has seen as many frames as the driver recorded (recorders get every frame)."""
        if not self.tap.caught_up(result.record.count, timeout_s=CATCH_UP_S):
            log.warning(
                "the watch tap saw %d frames, the run recorded %d; announcing the end anyway",
                self.tap.count,
                result.record.count,
            )
        self.tap.end(result.reason, result.t_end, result.ticks)


def run_keys(scenario: Scenario) -> Keys:
    return Keys(scenario.run.name, scenario.run.vehicle)


@contextmanager
def clock_bus(
    cfg: BusConfig,
    keys: Keys,
    flow: Dataflow,
    scenario_raw: JsonObject,
    *,
    lockstep: bool,
    access_control: Mapping[str, object] | None = None,
) -> Iterator[ClockSide]:
    """Open the driver's bus (see the module docstring) as the launcher identity (mTLS);
    a router clock may enforce the run's access control. Everything closes on exit.
    `lockstep`: the driver ticks every step (ticks.py: batched); else it tells the time."""
    with Bus(cfg, keys, identity=LAUNCHER, access_control=access_control) as bus:
        inbox = Inbox()
        bus.subscribe(keys.all_streams, inbox)
        bus.subscribe(keys.all_acks, inbox)  # a lockstep run's; a realtime run has none
        bus.watch_alive(inbox)
        claim(bus, keys, CLOCK)  # RoleTaken: another clock (a launch, a replay) runs it
        bus.watch_alive(inbox, keys.all_claims)  # a second claimant of a role: an alarm
        tap = serve_watchers(bus, keys, flow, scenario_raw)
        ticks = TickSender(bus, flow.names, express=not lockstep)
        bus.declare_alive(CLOCK)
        yield ClockSide(bus, inbox, ticks, tap)


def serve_watchers(
    bus: Bus, keys: Keys, flow: Dataflow, scenario_raw: JsonObject, *, listen: bool = True
) -> WatchTap:
    """What tools joining a run ask it for: its declared dataflow (a queryable) and the watch
    tap (copies, latest frames, scenario). A run's clock serves them, and so does a replay
    (`listen=False`: it feeds the tap its recorded frames, never the run's control keys)."""
    described = json.dumps(flow.describe(), sort_keys=True).encode()
    bus.serve(keys.dataflow, lambda: described, encoding=DATAFLOW_ENCODING)
    return WatchTap(bus, keys, scenario_raw, listen=listen)


def run_locally(
    scenario: Scenario,
    raw: JsonObject,
    log_dir: Path | None,
    service_module: str,
    make_driver: Callable[[RunContext], Driver],
) -> RunResult:
    """A whole run in this process and its children (see local_run), driven by one driver.
    Without a `log_dir` the services log to a temporary folder, removed after the run unless
    the run raised (then kept, and named in the log: a sweep of library calls leaves no
    litter, a failure its evidence)."""
    if log_dir is not None:
        return _run_locally(scenario, raw, log_dir, service_module, make_driver)
    tmp = Path(tempfile.mkdtemp(prefix="tidelink-logs-"))
    try:
        result = _run_locally(scenario, raw, tmp, service_module, make_driver)
    except BaseException:
        log.error("the run failed; its services' logs are kept in %s", tmp)
        raise
    shutil.rmtree(tmp, ignore_errors=True)
    return result


def _run_locally(
    scenario: Scenario,
    raw: JsonObject,
    log_dir: Path,
    service_module: str,
    make_driver: Callable[[RunContext], Driver],
) -> RunResult:
    mission = load_mission(scenario)
    with local_run(scenario, raw, mission.dataflow, service_module, log_dir) as (side, sup):
        ctx = RunContext(scenario=scenario, mission=mission, keys=run_keys(scenario), sup=sup)
        driver = make_driver(ctx)
        driver.await_alive(side.inbox)
        result = driver.drive(side.inbox, side.ticks, side.tap)
        side.announce_end(result)
        return result


@contextmanager
def local_run(
    scenario: Scenario, raw: JsonObject, flow: Dataflow, service_module: str, log_dir: Path
) -> Iterator[tuple[ClockSide, Supervisor]]:
    """This process is the router and the clock; each service is forked from the fork server.

    On exit the bus closes first (the clock's token vanishes, which releases the services),
    then the services get RELEASE_S to leave by themselves before they are stopped; realtime
    services, which leave on the stop Tick, get END_LINGER_S of that before the bus closes.
    """
    warm_up()  # the fork server imports the services while we open the router
    # [bus] listen: a fixed endpoint lets monitors on other machines join the run
    listen = scenario.bus.listen or (f"tcp/127.0.0.1:{free_port()}",)
    endpoint = connectable(listen[0])
    sup = Supervisor(log_dir, forked=True)
    cfg = scenario.bus.router_on(listen)
    keys = run_keys(scenario)
    # this process is the router: it enforces the run's access control (remote sessions only;
    # its own session, the clock, is the launcher identity and is not filtered)
    acl = access_control(run_grants(flow, keys)) if cfg.secured else None
    with tempfile.TemporaryDirectory(prefix="tidelink-") as tmp:
        raw_path = Path(tmp) / "scenario.json"
        raw_path.write_text(json.dumps(raw))
        try:
            lockstep = scenario.runtime.kind == "lockstep"
            with clock_bus(cfg, keys, flow, raw, lockstep=lockstep, access_control=acl) as side:
                for name in flow.names:
                    argv = [name, "--scenario-json", str(raw_path), "--connect", endpoint]
                    sup.start(name, ["-m", service_module, *argv])
                yield side, sup
                if not lockstep:  # (lockstep services leave only once the clock's token goes)
                    sup.wait_exited(sup.names(), END_LINGER_S)
        except BaseException:
            sup.stop()
            raise
        t_close = time.monotonic()
        if not sup.wait_exited(sup.names(), RELEASE_S):
            log.warning("a service did not exit after the run; stopping it")
        sup.stop()
        log.info("services exited %.2f s after the run", time.monotonic() - t_close)
