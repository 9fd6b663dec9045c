"""What a realtime service does with each message before its core sees it (issue 14): ticks
only from the clock's keys; data without or with forged routing, or of the wrong type,
dropped and counted against its input; and a loop whose steps outlast their period still
goes back to its inbox (no bus needed: events are handed in directly)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import pytest

from common.bus import Received
from common.config.scenario import load_scenario
from common.messages import LinkStats, NavFix, StateEstimate, Tick, encode_routing
from common.runtime.distributed.loop_times import PHASES, LoopTimes
from common.runtime.distributed.realtime_service import MAX_DELIVERY_AHEAD_S, RealtimeService
from common.runtime.distributed.service_process import ServiceSetup
from common.runtime.model.core import Emit
from common.runtime.model.record import Record
from common.runtime.run import loop_times

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
NAV = ("sensor", "nav")


def _service() -> RealtimeService:
    _, raw = load_scenario(DEFAULT)
    svc = RealtimeService(ServiceSetup.of("estimator", raw, "tcp/127.0.0.1:7447"))
    svc.t0 = time.monotonic()  # joined the mission clock at 0
    return svc


def _fix() -> NavFix:
    return NavFix(
        stamp=0.0,
        x=5.0,
        y=20.0,
        heading=0.0,
        speed=1.0,
        std_xy=0.5,
        std_heading=0.05,
        std_speed=0.1,
    )


def _queued(svc: RealtimeService) -> int:
    return len(svc.host._pending[NAV])


@pytest.fixture
def svc() -> RealtimeService:
    return _service()


def test_data_with_valid_routing_is_queued(svc: RealtimeService) -> None:
    key = svc.keys.stream(*NAV)
    assert not svc._handle(Received(key, _fix(), encode_routing(1, {"estimator": (0,)})))
    assert _queued(svc) == 1 and svc.host.dropped == {}


def test_data_without_or_with_bad_routing_is_dropped_and_counted(svc: RealtimeService) -> None:
    key = svc.keys.stream(*NAV)
    svc._handle(Received(key, _fix(), None))
    svc._handle(Received(key, _fix(), b"\xc1 not msgpack"))
    far = int((MAX_DELIVERY_AHEAD_S + 10.0) * 1e6)
    svc._handle(Received(key, _fix(), encode_routing(1, {"estimator": (far,)})))
    assert _queued(svc) == 0 and svc.host.dropped == {NAV: 3}
    assert svc.host.link_stats(0.0).inputs_dropped == {"sensor/nav->estimator": 3}


def test_only_the_clocks_keys_carry_ticks(svc: RealtimeService) -> None:
    stop = Tick(stamp=0.0, tick=1, time_us=0, stop=True)
    routed = encode_routing(1, {"estimator": (0,)})
    # a stop tick on a data key neither stops the service nor reaches the core
    assert not svc._handle(Received(svc.keys.stream(*NAV), stop, routed))
    assert svc.host.dropped == {NAV: 1}  # the wrong type for sensor/nav
    # data on a tick key is ignored; a stop tick there ends the run
    assert not svc._handle(Received(svc.keys.tick(["estimator"]), _fix(), None))
    assert svc._handle(Received(svc.keys.tick(["estimator"]), stop, None))


def test_every_tick_after_the_first_moves_the_clock_only_forward_to_the_least_delay() -> None:
    _, raw = load_scenario(DEFAULT)
    svc = RealtimeService(ServiceSetup.of("estimator", raw, "tcp/127.0.0.1:7447"))
    key = svc.keys.tick(["estimator"])

    def tick(t_s: float) -> None:
        t_us = round(t_s * 1e6)
        svc._handle(Received(key, Tick(stamp=t_s, tick=1, time_us=t_us), None))

    tick(10.0)  # joined at 10 s, from a Tick that may have been delayed
    # a Tick saying the launcher's clock reads 5 ms (wall) more is believed at once ...
    ahead = svc.now_us() + round(svc.scale * 5000)
    tick(ahead / 1e6)
    assert svc.now_us() >= ahead
    # ... one saying less (delayed more than the least delay seen) changes nothing
    before = svc.now_us()
    tick((before - round(svc.scale * 500_000)) / 1e6)
    assert 0 <= svc.now_us() - before < svc.scale * 1000


class _Sent:
    """A publisher that keeps what is put on it."""

    def __init__(self) -> None:
        self.frames: list[bytes] = []

    def put_bytes(self, data: bytes, attachment: bytes | None = None) -> None:
        self.frames.append(data)


def test_a_step_longer_than_its_period_goes_back_to_the_inbox(
    svc: RealtimeService, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Every step of this service takes two periods: the due events run once, then the loop
    returns to its inbox (where a stop Tick, or the inputs that would shorten the steps,
    wait) instead of stepping on without end."""
    period_s = svc.host.period_us / 1e6 / svc.scale
    svc.t0 = time.monotonic() - 10.0 / svc.scale  # 10 mission seconds behind its schedule
    core_step = svc.host.core.step
    steps: list[float] = []

    def slow_step(t: float) -> list[Emit]:
        steps.append(t)
        assert len(steps) < 5, "stepped on without going back to the inbox"
        assert svc.t0 is not None
        svc.t0 -= 2 * period_s  # its clock moves on two periods, as if the step took that long
        return core_step(t)

    monkeypatch.setattr(svc.host.core, "step", slow_step)
    pubs: dict[str, Any] = {s: _Sent() for s in svc.host.streams}
    svc._run_due(pubs)
    assert len(steps) == 1 and svc.skipped > 0  # the missed periods skipped, one step run
    assert svc.times.counters()["loop.skipped_periods"] == svc.skipped  # and in its statistics
    assert pubs["state"].frames  # and what it emitted published
    svc._run_due(pubs)
    assert len(steps) == 2  # the next call: the next step, late by a period


def test_loop_times_are_reported_as_microsecond_quantiles_per_phase() -> None:
    times = LoopTimes()
    assert times.counters() == {}  # nothing before the first tick
    for k in range(1, 101):  # wake 1..100 us, step 10x that, publish constant 5 us
        times.record(k * 1e-6, k * 1e-5, 5e-6)
    times.record(-1e-6, 0.0, 0.0)  # a clock read a hair early counts as on time
    c = times.counters()
    assert c["loop.wake_p50_us"] == pytest.approx(50, rel=0.01)
    assert c["loop.step_p95_us"] == pytest.approx(950, rel=0.01)
    assert (c["loop.wake_max_us"], c["loop.step_max_us"]) == (100, 1000)
    assert c["loop.publish_p50_us"] == 5


def test_a_runs_loop_times_are_each_services_last_ones() -> None:
    # what the benchmarks read from a realtime run's record (scripts/bench runtime, fleet)
    def stats(source: str, seq: int, counters: dict[str, int]) -> LinkStats:
        return LinkStats(stamp=float(seq), source=source, seq=seq, links=(), counters=counters)

    record = Record()
    record.add("planner", "stats", stats("planner", 1, {"loop.step_p50_us": 900, "steps": 3}))
    record.add("planner", "stats", stats("planner", 2, {"loop.step_p50_us": 4300, "steps": 9}))
    record.add("vehicle", "stats", stats("vehicle", 1, {}))  # lockstep, inproc: no loop times
    assert loop_times(record) == {"planner": {"loop.step_p50_us": 4300}}


def test_a_realtime_hosts_statistics_carry_its_loop_times(svc: RealtimeService) -> None:
    pubs: dict[str, Any] = {s: _Sent() for s in svc.host.streams}
    svc.t0 = time.monotonic() - 1.0 / svc.scale  # a second in: a step and statistics are due
    svc._run_due(pubs)
    stats = svc.host.link_stats(1.0)
    assert stats.counters["loop.step_p50_us"] > 0
    # a second behind its schedule, it skipped the periods it missed, and says how many
    assert set(stats.counters) == {
        f"loop.{phase}_{q}_us" for phase in PHASES for q in ("p50", "p95", "max")
    } | {"loop.skipped_periods"}
    assert stats.counters["loop.skipped_periods"] == svc.skipped > 0


class _Logged(_Sent):
    """A publisher that notes each put in a log shared with the core's prepare."""

    def __init__(self, stream: str, log: list[str]) -> None:
        super().__init__()
        self.stream, self.log = stream, log

    def put_bytes(self, data: bytes, attachment: bytes | None = None) -> None:
        self.log.append(f"put {self.stream}")
        super().put_bytes(data, attachment)


def _planner(delay_s: float) -> tuple[RealtimeService, float]:
    """A realtime planner at its first step, an estimate in hand; and its first step's time."""
    _, raw = load_scenario(
        DEFAULT,
        [
            "planner.first_plan_wait_s=0",
            f"runtime.prepare_delay_s={delay_s}",
            "runtime.time_scale=1",  # mission time is wall time: the test takes milliseconds
        ],
    )
    svc = RealtimeService(ServiceSetup.of("planner", raw, "tcp/127.0.0.1:7447"))
    first_s = svc.host.next_step_us / 1e6
    _at(svc, first_s + 0.001)  # its first step is due
    est = StateEstimate(
        stamp=0.0, x=5.0, y=20.0, theta=0.0, v=0.0, w=0.0, covariance=(0.0,) * 25, seq=1
    )
    svc.host.accept(est, "estimator", "state", (0,), -1)
    return svc, first_s


def _logged(
    svc: RealtimeService, monkeypatch: pytest.MonkeyPatch
) -> tuple[dict[str, Any], list[str]]:
    """Publishers and the core's prepare, noting each put and prepare in one log."""
    log: list[str] = []
    core_prepare = svc.host.core.prepare  # type: ignore[attr-defined]

    def prepare(t_next: float) -> None:
        log.append(f"prepare {t_next:.3f}")
        core_prepare(t_next)

    monkeypatch.setattr(svc.host.core, "prepare", prepare)
    return {s: _Logged(s, log) for s in svc.host.streams}, log


def _at(svc: RealtimeService, mission_s: float) -> None:
    """Set the service's clock to mission_s now (a first step that plans takes ~0.1 s)."""
    svc.t0 = time.monotonic() - mission_s / svc.scale


def test_a_realtime_planner_prepares_its_next_step_once_its_command_is_out(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    svc, first_s = _planner(0.0)
    pubs, log = _logged(svc, monkeypatch)
    svc._run_due(pubs)
    # at once, for its next step, once the command went out
    assert log[-1] == f"prepare {first_s + svc.host.period_us / 1e6:.3f}"
    assert "put cmd" in log[:-1]
    # its statistics say how long preparing took, apart from the tick's phases
    assert {"loop.prepare_p50_us", "loop.prepare_max_us"} <= set(svc.times.counters())


def test_a_realtime_planner_prepares_its_next_step_after_the_delay(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    svc, first_s = _planner(0.05)  # the default is 0.02 s (runtime.prepare_delay_s)
    pubs, log = _logged(svc, monkeypatch)
    svc._run_due(pubs)
    assert "put cmd" in log and not any(e.startswith("prepare") for e in log)
    assert svc._prepare_at_us == round((first_s + 0.05) * 1e6)  # when the loop wakes for it
    _at(svc, first_s + 0.02)
    svc._run_due(pubs)
    assert not any(e.startswith("prepare") for e in log)  # not yet
    _at(svc, first_s + 0.055)
    svc._run_due(pubs)
    assert log[-1] == f"prepare {first_s + 0.1:.3f}" and svc._prepare_at_us is None


def test_a_prepare_still_waiting_when_the_next_step_is_due_runs_before_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    svc, first_s = _planner(0.5)  # longer than the 0.1 s period
    pubs, log = _logged(svc, monkeypatch)
    svc._run_due(pubs)
    _at(svc, first_s + 0.101)  # the next step is due, the prepare (due at +0.5 s) is not
    del log[:]
    svc._run_due(pubs)
    assert log[0] == f"prepare {first_s + 0.1:.3f}"  # first, for the step now due
    assert "put cmd" in log[1:]
