"""The Host under a flood (issue 14, defect 8): each input holds at most max_queued deliveries,
the ones due first are dropped and counted, and the counts reach the service's LinkStats."""

from __future__ import annotations

from collections.abc import Mapping

from common.config.network import NetworkConfig
from common.messages import NavFix, VelocityCommand
from common.netmodel import NetworkModel
from common.runtime.model.core import Delivery, Emit, ServiceCore
from common.runtime.model.dataflow import CoreContext, Dataflow, Input, Output, Service
from common.runtime.model.host import Host


def _unused(ctx: CoreContext) -> ServiceCore:
    raise AssertionError("these tests build their cores themselves")


class Judging:
    """A core that records deliveries and reports rejections and resets, like the estimator."""

    def __init__(self) -> None:
        self.got: list[tuple[float, int]] = []  # (delivery time, seq) of commands
        self.pings = 0

    def deliver(self, d: Delivery) -> list[Emit]:
        if d.stream == "cmd":
            self.got.append((d.t, d.msg.seq))
        else:
            self.pings += 1
        return []

    def step(self, t: float) -> list[Emit]:
        return []

    @property
    def inputs_rejected(self) -> Mapping[str, int]:
        return {"cmd.future": 2}

    @property
    def resets(self) -> Mapping[str, int]:
        return {"vehicle_filter": 1}


def _host(max_queued: int, period: float = 1.0) -> tuple[Host, Judging]:
    flow = Dataflow.declare(
        Service(
            name="talker",
            factory=_unused,
            outputs=(Output(stream="cmd", msg_type=VelocityCommand),),
        ),
        Service(name="pinger", factory=_unused, outputs=(Output(stream="ping", msg_type=NavFix),)),
        Service(
            name="listener",
            factory=_unused,
            period_s=period,
            inputs=(
                Input(
                    source="talker", stream="cmd", msg_type=VelocityCommand, max_queued=max_queued
                ),
                Input(source="pinger", stream="ping", msg_type=NavFix, wake=True),
            ),
        ),
    )
    core = Judging()
    return Host(flow, "listener", core, NetworkModel(NetworkConfig(), seed=1)), core


def _cmd(seq: int) -> VelocityCommand:
    return VelocityCommand(stamp=0.0, seq=seq, v=1.0, w=0.0, path_id=0)


def test_a_flood_keeps_the_newest_max_queued_deliveries_and_counts_the_rest() -> None:
    host, core = _host(max_queued=8)
    for seq in range(1, 1001):  # 1000 commands due one microsecond apart
        host.accept(_cmd(seq), "talker", "cmd", (10 + seq,), sent_tick=0)
    host.run_tick(1, 0)  # the step at 0: nothing due yet
    host.run_tick(2, 1_000_000)  # the step at 1 s: what survived
    assert [seq for _, seq in core.got] == list(range(993, 1001))
    assert host.dropped == {("talker", "cmd"): 992}
    stats = host.link_stats(1.0)
    assert stats.inputs_dropped == {"talker/cmd->listener": 992}
    assert stats.inputs_rejected == {"cmd.future": 2} and stats.resets == {"vehicle_filter": 1}


def test_copies_of_one_message_never_compare_the_messages() -> None:
    host, core = _host(max_queued=8)
    msg = _cmd(7)
    for _ in range(20):  # a replayed message: same seq, same delivery time, same copy
        host.accept(msg, "talker", "cmd", (5, 5), sent_tick=0)
    host.run_tick(1, 0)
    host.run_tick(2, 1_000_000)
    assert len(core.got) == 8 and host.dropped == {("talker", "cmd"): 32}


def test_deliveries_waiting_for_the_step_are_bounded_too() -> None:
    # wake deliveries tick the host between steps: commands due then wait in the ready buffer
    host, core = _host(max_queued=4, period=10.0)
    host.run_tick(1, 0)
    seq = 0
    for k in range(1, 6):  # five wake ticks, four commands due before each
        for _ in range(4):
            seq += 1
            host.accept(_cmd(seq), "talker", "cmd", (k * 100_000 - 1,), sent_tick=k)
        ping = NavFix(
            stamp=0.0, seq=k, x=0, y=0, heading=0, speed=0, std_xy=0, std_heading=0, std_speed=0
        )
        host.accept(ping, "pinger", "ping", (k * 100_000,), sent_tick=k)
        host.run_tick(k + 1, k * 100_000)
    assert core.pings == 5 and core.got == []  # the commands wait for the step
    host.run_tick(10, 10_000_000)  # the step: the last four commands only
    assert [seq for _, seq in core.got] == [17, 18, 19, 20]
    assert host.dropped == {("talker", "cmd"): 16}


def test_an_input_never_queues_more_than_max_queued_whatever_the_schedule() -> None:
    host, _ = _host(max_queued=16)
    for seq in range(1, 5001):  # deliveries spread over far-apart times, in any order
        host.accept(_cmd(seq), "talker", "cmd", ((seq * 7919) % 5000 * 1000,), sent_tick=0)
        assert len(host._pending[("talker", "cmd")]) <= 16
    assert host.dropped[("talker", "cmd")] == 5000 - 16


def test_the_metrics_total_every_services_last_input_counts() -> None:
    import msgspec

    from common.messages import LinkStats, replace
    from common.runtime.model.record import Record
    from common.runtime.run import input_health

    record = Record()
    old = LinkStats(stamp=1.0, seq=1, links=(), inputs_rejected={"nav.future": 1})
    est = LinkStats(
        stamp=2.0,
        seq=2,
        links=(),
        inputs_dropped={"sensor/nav->estimator": 40},
        inputs_rejected={"nav.future": 3, "obstacles.too_large": 1},
        resets={"vehicle_filter": 1, "tracks": 0},
    )
    plan = LinkStats(stamp=2.0, seq=1, links=(), inputs_rejected={"state.stale": 2})
    for service, msg in (("estimator", old), ("estimator", est), ("planner", plan)):
        # the record keeps a stream's messages from its own publisher only (envelope source)
        record.add(service, "stats", replace(msg, source=service))
    assert msgspec.structs.asdict(input_health(record)) == {
        "inputs_rejected": 6,
        "inputs_rejected_by_reason": {
            "estimator": {"nav.future": 3, "obstacles.too_large": 1},
            "planner": {"state.stale": 2},
        },
        "inputs_dropped": 40,
        "inputs_dropped_by_link": {"sensor/nav->estimator": 40},
        "filter_resets": 1,
        "filter_resets_by_service": {"estimator": {"tracks": 0, "vehicle_filter": 1}},
    }
