"""The inproc runtime: every core in one process on a discrete-event clock, no Zenoh."""

from __future__ import annotations

import logging

from common.config.scenario import Scenario
from common.messages import decode_own
from common.netmodel import NetworkModel
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.host import NEVER, Host, Outgoing
from common.runtime.model.mission import load_mission, mission_record
from common.runtime.model.record import Record
from common.runtime.model.result import RunResult

log = logging.getLogger("tidelink.inproc")


def build_host(scenario: Scenario, flow: Dataflow, name: str) -> Host:
    """The Host of one declared service: its core from its factory, its own network model
    (its outgoing links)."""
    return Host(
        flow,
        name,
        flow.service(name).make_core(scenario),
        NetworkModel(
            scenario.network,
            seed=scenario.run.seed,
            placement=scenario.placement,
            vehicle_start=(scenario.world.start.x_m, scenario.world.start.y_m),
        ),
        stats_period_s=scenario.runtime.stats_period_s,
    )


def route(
    out: list[Outgoing], source: str, tick: int, hosts: dict[str, Host], record: Record
) -> None:
    """Record what a host published and queue each message at its receivers."""
    for o in out:
        # decoded from the bytes, exactly what a Zenoh subscriber would see (decode_own: the
        # host encoded them from a message checked when it was built, so not checked again)
        msg = decode_own(o.data)
        record.add(source, o.stream, msg)
        for receiver, times in o.schedule.items():
            if times:
                hosts[receiver].accept(msg, source, o.stream, times, tick)


def run_inproc(scenario: Scenario) -> RunResult:
    """Run a mission to its end in this process."""
    mission = load_mission(scenario)
    flow = mission.dataflow
    hosts = {name: build_host(scenario, flow, name) for name in flow.names}
    record = mission_record(mission)
    max_us = round(mission.max_time_s * 1e6)
    tick, t_us, reason = 0, 0, "max_time"
    ordered = [(name, hosts[name]) for name in sorted(hosts)]
    events = [h.next_event_us() for _, h in ordered]  # each host's, in that order
    while True:
        # only hosts with something due take part (lockstep wakes exactly the same ones)
        for (name, host), event_us in zip(ordered, events, strict=True):
            if event_us <= t_us:
                route(host.run_tick(tick, t_us), name, tick, hosts, record)
                host.prepare()  # as the distributed runtimes do, once the outputs are out
        end = mission.observe(record)
        if end is not None:
            reason = end
            break
        events = [h.next_event_us() for _, h in ordered]
        nxt = min(events)
        if nxt > max_us or nxt >= NEVER:
            break
        t_us, tick = nxt, tick + 1
    final_tick = tick + 1
    for name in sorted(hosts):  # final statistics, as the lockstep stop tick publishes them
        route([hosts[name].publish_stats(final_tick, t_us)], name, final_tick, hosts, record)
    log.info("inproc run ended at t=%.3f s after %d ticks: %s", t_us / 1e6, tick + 1, reason)
    metrics = mission.metrics(record)
    return RunResult(reason, t_us / 1e6, tick + 1, record, metrics)
