"""What every multi-process runtime's service process shares: its host, its bus wiring, main()."""

from __future__ import annotations

import argparse
import cProfile
import json
import logging
import os
import resource
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import NamedTuple, Protocol

from common.bus import CLOCK, Bus, Inbox, Keys, Publisher, Received
from common.bus.watcher import watched
from common.config.bus import BusConfig
from common.config.scenario import Scenario, scenario_from_raw
from common.jsonsafe import JsonObject
from common.messages import WireError, decode_routing
from common.runtime.distributed.claim import RoleTaken
from common.runtime.model.host import Host
from common.runtime.model.inproc import build_host
from common.runtime.model.mission import Mission, load_mission
from common.runtime.processes.signals import Shutdown, install_shutdown_handlers

log = logging.getLogger("tidelink.service")
# a directory: every service process writes its cProfile there as NAME.prof (developers)
PROFILE_ENV = "TIDELINK_PROFILE"


@dataclass(frozen=True)
class ServiceSetup:
    """What a service process is given: its scenario and mission, its Host, its run's keys
    and bus."""

    name: str
    scenario: Scenario
    mission: Mission
    host: Host
    keys: Keys
    bus_cfg: BusConfig

    @classmethod
    def of(cls, name: str, raw: JsonObject, connect: str) -> ServiceSetup:
        """Validate the scenario and build this service's Host (the whole dataflow is
        validated; only this service's core is built); a client of `connect`."""
        scenario = scenario_from_raw(raw)
        mission = load_mission(scenario)
        flow = mission.dataflow
        if name not in flow.services:
            raise SystemExit(f"unknown service {name!r}; this mission has {', '.join(flow.names)}")
        return cls(
            name=name,
            scenario=scenario,
            mission=mission,
            host=build_host(scenario, flow, name),
            keys=Keys(scenario.run.name, scenario.run.vehicle),
            bus_cfg=scenario.bus.client_of(connect),  # the run's security (mTLS) included
        )


def wire(bus: Bus, host: Host, keys: Keys, inbox: Inbox, *, express: bool) -> dict[str, Publisher]:
    """Subscribe the host's inputs and the clock; one publisher per output stream and stats."""
    for i in host.inputs:
        bus.subscribe_stream(i.source, i.stream, inbox)
    bus.subscribe(keys.ticks_for(host.name), inbox)
    bus.watch_alive(inbox, keys.alive(CLOCK))
    return {s: bus.publisher(host.name, s, express=express) for s in host.streams}


def resume_from_tap(bus: Bus, host: Host, keys: Keys, t_us: int, *, timeout_s: float) -> None:
    """A core that resumes (Resumes), joining a running mission, takes up from the newest
    message its previous process published on each stream, as the run's watch tap kept them
    (common/bus/tap.py); with none (its first start, or no tap answered) it starts over."""
    if not host.resumes:
        return
    own = {}
    # its own keys only: that is what its certificate may ask for in a secured run (acl.py)
    for f in bus.query(keys.latest(host.name, "*"), timeout_s=timeout_s):
        try:
            w = watched(f)
        except (ValueError, WireError):
            continue
        own[w.stream] = w.payload
    what = host.resume(own, t_us)
    if what is None:
        log.info("%s: nothing of an earlier process of it found: starting over", host.name)
    else:
        log.info("%s: resumed %s", host.name, what)


class Routed(NamedTuple):
    """A data message's input (source, stream), the tick it was sent in and its modelled
    delivery times to this service (none: the link model lost it)."""

    source: str
    stream: str
    sent_tick: int
    times_us: tuple[int, ...]


def take_data(host: Host, keys: Keys, ev: Received) -> Routed | None:
    """The routing of a data message for this host, or None: a message on a key that is not
    an input is not delivered (see `route` for the routing attachment)."""
    try:
        source, stream = keys.split(ev.key)
    except ValueError:  # a key with more chunks: a tick key, or nothing we subscribed to
        return None
    return route(host, source, stream, ev.attachment)


def route(host: Host, source: str, stream: str, attachment: bytes | None) -> Routed | None:
    """The routing of a message of `source`/`stream` for this host, or None: without a valid
    routing attachment it is not delivered; the host counts it among its inputs' drops and
    logs it once per input and reason per mission second (a flood of them costs one line a
    second, not one a message)."""
    if attachment is None:
        host.count_dropped(source, stream, 1, "no routing attachment")
        return None
    try:
        sent_tick, schedule = decode_routing(attachment)
    except WireError as exc:
        host.count_dropped(source, stream, 1, "bad routing attachment", str(exc))
        return None
    return Routed(source, stream, sent_tick, schedule.get(host.name, ()))


class Runnable(Protocol):
    """A service process body: run() until the run ends, returning the exit code."""

    def run(self) -> int: ...


def service_main(make: Callable[[ServiceSetup], Runnable], doc: str, argv: list[str] | None) -> int:
    """Parse `NAME --scenario-json FILE --connect ENDPOINT`, then run until done or signalled."""
    p = argparse.ArgumentParser(description=doc)
    p.add_argument("name")
    p.add_argument("--scenario-json", required=True, type=Path)
    p.add_argument("--connect", required=True)
    a = p.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO, format=f"%(asctime)s {a.name} %(levelname)s %(message)s"
    )
    install_shutdown_handlers()
    raw = json.loads(a.scenario_json.read_text())
    try:
        service = make(ServiceSetup.of(a.name, raw, a.connect))
        profile_dir = os.environ.get(PROFILE_ENV)
        if not profile_dir:
            return service.run()
        with cProfile.Profile() as prof:  # a developer's view of where a service's time goes
            try:
                return service.run()
            finally:
                prof.dump_stats(Path(profile_dir) / f"{a.name}.prof")
    except Shutdown as exc:
        log.info("stopping on %s", exc)
        return 0
    except RoleTaken as exc:
        log.error("%s", exc)
        return 1
    finally:
        # what this process cost the machine: the measure of how many cores a run needs
        use = resource.getrusage(resource.RUSAGE_SELF)
        log.info("%s: used %.2f s of CPU", a.name, use.ru_utime + use.ru_stime)
