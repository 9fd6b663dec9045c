"""Unit tests of the shared Host and the inproc runtime on the toy loop (no processes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.network import NetworkConfig
from common.config.scenario import load_scenario
from common.messages import TruthState, VelocityCommand, decode
from common.netmodel import NetworkModel
from common.runtime.core import CoreSpec, Delivery, Emit, InputSpec, OutputSpec, QueuePolicy
from common.runtime.dataflow import Dataflow, DataflowError
from common.runtime.host import Host
from common.runtime.inproc import run_inproc


class Talker:
    def __init__(self) -> None:
        self.spec = CoreSpec(
            name="talker",
            outputs=(OutputSpec(stream="cmd", msg_type=VelocityCommand),),
            period_s=0.1,
        )

    def deliver(self, d: Delivery) -> list[Emit]:
        return []

    def step(self, t: float) -> list[Emit]:
        return [Emit(stream="cmd", msg=VelocityCommand(stamp=t, v=t, w=0.0, path_id=0))]


class Listener:
    def __init__(self, policy: QueuePolicy, period: float = 0.1) -> None:
        self.spec = CoreSpec(
            name="listener",
            period_s=period,
            inputs=(
                InputSpec(source="talker", stream="cmd", msg_type=VelocityCommand, policy=policy),
            ),
        )
        self.got: list[tuple[float, float]] = []  # (delivery time, stamp)
        self.steps: list[float] = []

    def deliver(self, d: Delivery) -> list[Emit]:
        self.got.append((d.t, d.msg.stamp))
        return []

    def step(self, t: float) -> list[Emit]:
        self.steps.append(t)
        return []


def _pair(policy: QueuePolicy, listener_period: float = 0.1) -> tuple[Host, Host, Listener]:
    talker, listener = Talker(), Listener(policy, listener_period)
    flow = Dataflow.of([talker.spec, listener.spec])
    net = NetworkConfig()
    return (
        Host(talker, flow, NetworkModel(net, seed=1)),
        Host(listener, flow, NetworkModel(net, seed=1)),
        listener,
    )


def _run(th: Host, lh: Host, until_us: int) -> None:
    tick, t = 0, 0
    while t <= until_us:
        for host in (th, lh):
            for o in host.run_tick(tick, t):
                for receiver, times in o.schedule.items():
                    if receiver == "listener":
                        lh.accept(decode(o.data), "talker", o.stream, times, tick)
        t = min(th.next_event_us(), lh.next_event_us())
        tick += 1


def test_zero_delay_message_is_not_delivered_in_the_tick_it_was_sent() -> None:
    th, lh, listener = _pair(QueuePolicy.ALL)
    _run(th, lh, 300_000)
    # sent at 0.0 with zero delay: handed over at the listener's next step (0.1), not at 0.0
    assert listener.got[0] == (0.0, 0.0)
    assert listener.steps[:2] == [0.0, 0.1]
    assert len(listener.got) == 3  # stamps 0.0, 0.1, 0.2 (0.3 is sent in the last tick)


def test_newest_policy_keeps_only_the_last_delivery_between_steps() -> None:
    th, lh, listener = _pair(QueuePolicy.NEWEST, listener_period=0.3)
    _run(th, lh, 900_000)
    stamps = [s for _, s in listener.got]
    # steps at 0.0, 0.3, 0.6, 0.9; of the commands stamped 0.0..0.8 only the newest
    # before each step is handed over
    assert stamps == [0.2, 0.5, 0.8]
    assert lh.superseded == 6


def test_dataflow_rejects_an_input_nobody_publishes() -> None:
    listener = Listener(QueuePolicy.ALL)
    with pytest.raises(DataflowError, match="talker/cmd is not an output"):
        Dataflow.of([listener.spec])


def test_dataflow_rejects_a_type_mismatch() -> None:
    talker = Talker()
    wrong = CoreSpec(
        name="listener", inputs=(InputSpec(source="talker", stream="cmd", msg_type=TruthState),)
    )
    with pytest.raises(DataflowError, match="expects TruthState"):
        Dataflow.of([talker.spec, wrong])


def test_inproc_testloop_converges_and_is_repeatable(testloop_toml: Path) -> None:
    s, _ = load_scenario(testloop_toml)
    a, b = run_inproc(s), run_inproc(s)
    assert a.metrics == b.metrics
    assert a.metrics["final_error"] < 0.5  # the P loop reaches its set-point despite the network
    s2, _ = load_scenario(testloop_toml, seed=2)
    assert run_inproc(s2).metrics["trajectory_sha256"] != a.metrics["trajectory_sha256"]


def test_inproc_counts_link_drops(testloop_toml: Path) -> None:
    from common.messages import LinkStats

    s, _ = load_scenario(testloop_toml)
    r = run_inproc(s)
    stats = r.record.stream("filter", "stats")[-1]
    assert isinstance(stats, LinkStats)
    (link,) = stats.links
    assert link.link == "filter/state->ctrl"
    assert link.dropped_outage > 0  # the outage on the filter's links (4.0 s to 5.5 s)
    assert link.dropped_loss > 0
    assert (
        link.sent == link.delivered + link.dropped_loss + link.dropped_outage + link.dropped_queue
    )
