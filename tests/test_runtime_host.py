"""Unit tests of the shared Host and the inproc runtime on the toy loop (no processes)."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.network import NetworkConfig
from common.config.scenario import load_scenario
from common.messages import TruthState, VelocityCommand, decode
from common.netmodel import NetworkModel
from common.runtime.model.core import Delivery, Emit, QueuePolicy, ServiceCore
from common.runtime.model.dataflow import (
    CoreContext,
    Dataflow,
    DataflowError,
    Input,
    Output,
    Service,
)
from common.runtime.model.host import NEVER, Host
from common.runtime.model.inproc import run_inproc


class Talker:
    def deliver(self, d: Delivery) -> list[Emit]:
        return []

    def step(self, t: float) -> list[Emit]:
        return [Emit(stream="cmd", msg=VelocityCommand(stamp=t, v=t, w=0.0, path_id=0))]


class Listener:
    def __init__(self) -> None:
        self.got: list[tuple[float, float]] = []  # (delivery time, stamp)
        self.steps: list[float] = []

    def deliver(self, d: Delivery) -> list[Emit]:
        self.got.append((d.t, d.msg.stamp))
        return []

    def step(self, t: float) -> list[Emit]:
        self.steps.append(t)
        return []


def _unused(ctx: CoreContext) -> ServiceCore:
    raise AssertionError("these tests build their cores themselves")


TALKER = Service(
    name="talker",
    factory=_unused,
    outputs=(Output(stream="cmd", msg_type=VelocityCommand),),
    period_s=0.1,
)


def _listener(
    policy: QueuePolicy = QueuePolicy.ALL, period: float | None = 0.1, wake: bool = False
) -> Service:
    cmd = Input(source="talker", stream="cmd", msg_type=VelocityCommand, policy=policy, wake=wake)
    return Service(name="listener", factory=_unused, period_s=period, inputs=(cmd,))


def _pair(service: Service) -> tuple[Host, Host, Listener]:
    flow = Dataflow.declare(TALKER, service)
    listener = Listener()
    net = NetworkConfig()
    return (
        Host(flow, "talker", Talker(), NetworkModel(net, seed=1)),
        Host(flow, "listener", listener, NetworkModel(net, seed=1)),
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
    th, lh, listener = _pair(_listener())
    _run(th, lh, 300_000)
    # sent at 0.0 with zero delay: handed over at the listener's next step (0.1), not at 0.0
    assert listener.got[0] == (0.0, 0.0)
    assert listener.steps[:2] == [0.0, 0.1]
    assert len(listener.got) == 3  # stamps 0.0, 0.1, 0.2 (0.3 is sent in the last tick)


def test_newest_policy_keeps_only_the_last_delivery_between_steps() -> None:
    th, lh, listener = _pair(_listener(QueuePolicy.NEWEST, period=0.3))
    _run(th, lh, 900_000)
    stamps = [s for _, s in listener.got]
    # steps at 0.0, 0.3, 0.6, 0.9; of the commands stamped 0.0..0.8 only the newest
    # before each step is handed over
    assert stamps == [0.2, 0.5, 0.8]
    assert lh.superseded == 6


def test_an_event_driven_service_steps_only_on_wake_deliveries() -> None:
    th, lh, listener = _pair(_listener(period=None, wake=True))
    assert lh.next_event_us() == NEVER  # nothing queued: it never needs a tick
    _run(th, lh, 300_000)
    assert listener.steps == []
    # every command is handed over at its own delivery time (zero delay: its stamp), in the
    # tick after the one it was sent in, without waiting for a periodic step
    assert listener.got == [(0.0, 0.0), (0.1, 0.1), (0.2, 0.2), (0.3, 0.3)]


def test_dataflow_rejects_an_input_nobody_publishes() -> None:
    with pytest.raises(DataflowError, match="talker/cmd is not an output"):
        Dataflow.declare(_listener())


def test_dataflow_rejects_a_type_mismatch() -> None:
    wrong = Service(
        name="listener",
        factory=_unused,
        inputs=(Input(source="talker", stream="cmd", msg_type=TruthState),),
    )
    with pytest.raises(DataflowError, match="expects TruthState"):
        Dataflow.declare(TALKER, wrong)


@pytest.mark.parametrize(
    ("services", "problem"),
    [
        ((TALKER, TALKER), "two services are named 'talker'"),
        ((Service(name="x", factory=_unused, period_s=0.0),), "period_s must be > 0"),
        ((Service(name="x", factory=_unused, period_s=None),), "needs a wake input"),
    ],
)
def test_dataflow_rejects_a_bad_declaration(services: tuple[Service, ...], problem: str) -> None:
    with pytest.raises(DataflowError, match=problem):
        Dataflow.declare(*services)


def test_dataflow_describes_services_links_and_types_as_plain_data() -> None:
    d = Dataflow.declare(TALKER, _listener(QueuePolicy.NEWEST)).describe()
    assert d["links"] == ["talker/cmd->listener"]
    listener = next(s for s in d["services"] if s["name"] == "listener")
    assert listener["inputs"] == [
        {
            "source": "talker",
            "stream": "cmd",
            "type": "VelocityCommand",
            "policy": "newest",
            "wake": False,
            "max_queued": 64,
        }
    ]
    talker = next(s for s in d["services"] if s["name"] == "talker")
    assert talker["outputs"] == [{"stream": "cmd", "type": "VelocityCommand"}]


def test_inproc_testloop_converges_and_is_repeatable(testloop_toml: Path) -> None:
    s, _ = load_scenario(testloop_toml)
    a, b = run_inproc(s), run_inproc(s)
    assert a.metrics == b.metrics
    assert a.metrics.final_error < 0.5  # the P loop reaches its set-point despite the network
    s2, _ = load_scenario(testloop_toml, seed=2)
    assert run_inproc(s2).metrics.trajectory_sha256 != a.metrics.trajectory_sha256


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


def test_in_virtual_time_the_delay_a_receiver_measures_is_the_modelled_one() -> None:
    from common.config.scenario import load_scenario
    from common.runtime.model.inproc import run_inproc
    from common.runtime.run import link_stats

    s, _ = load_scenario("configs/experiments/scenarios/small.toml")
    links = link_stats(run_inproc(s).record)
    lossy = [v for v in links.values() if v["delay_p50_s"] > 0]
    assert lossy, links  # the scenario models delay somewhere
    for name, v in links.items():
        for q in ("p50", "p95"):
            # delivery times are whole microseconds (1 % histogram bins), but the sender's
            # last count has messages the receiver's has not had yet (in flight when it last
            # counted: 1 of 126 fixes, 2 of 252 tracks), which moves a nearest rank by as many
            # samples: measured up to 6 % at p95 of ~130 samples. A delivery one period late
            # would be 100 % off.
            assert v[f"measured_delay_{q}_s"] == pytest.approx(v[f"delay_{q}_s"], rel=0.1), name


class Preparing(Listener):
    """A listener that prepares its next step (core.Prepares) and logs what it sees then."""

    def __init__(self) -> None:
        super().__init__()
        self.prepared: list[tuple[float, int, int]] = []  # (t_next, steps, deliveries) then

    def prepare(self, t_next: float) -> None:
        self.prepared.append((t_next, len(self.steps), len(self.got)))


def test_a_core_prepares_after_each_step_for_the_next_one_and_only_then() -> None:
    flow = Dataflow.declare(TALKER, _listener(wake=True, period=0.25))
    core = Preparing()
    host = Host(flow, "listener", core, NetworkModel(NetworkConfig(), seed=1))
    assert host.prepare() is False  # nothing stepped yet
    host.run_tick(1, 0)  # the step at 0
    assert host.prepare() is True and core.prepared == [(0.25, 1, 0)]
    assert host.prepare() is False  # once per step
    cmd = VelocityCommand(stamp=0.0, v=0.0, w=0.0, path_id=0, source="talker", seq=1)
    host.accept(cmd, "talker", "cmd", (100_000,), 1)
    host.run_tick(2, 100_000)  # a wake delivery, no step: nothing to prepare
    assert core.got and host.prepare() is False
    host.run_tick(3, 250_000)
    assert host.prepare() is True and core.prepared[-1] == (0.5, 2, 1)


def test_inproc_lets_a_core_prepare_after_each_of_its_steps(testloop_toml: Path) -> None:
    from tests.helpers import testloop

    steps: list[float] = []
    prepared: list[float] = []

    class PreparingFilter(testloop.Filter):
        def step(self, t: float) -> list[Emit]:
            steps.append(t)
            return super().step(t)

        def prepare(self, t_next: float) -> None:
            prepared.append(t_next)

    s, _ = load_scenario(testloop_toml, ["run.max_time_s=1.0"])
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(testloop, "Filter", PreparingFilter)
        run_inproc(s)
    # after every step, for the one after it (the filter steps every 0.1 s)
    assert len(steps) >= 10 and prepared == pytest.approx([t + 0.1 for t in steps])
