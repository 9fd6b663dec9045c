"""A small closed loop of toy cores (sensor, filter, P controller, integrator plant).

It exercises the runtimes end to end without the AUV services: a noisy sensor samples the
plant, a filter smooths it, a proportional controller drives the plant to a set-point, the
plant integrates the command. Select it with `[run] mission = "testloop"` (registered for
the session by tests/conftest.py, with `missions_env`; the older spelling
"tests.helpers.testloop:TestLoop" names it too) and set its parameters (TestLoopParams) in the
scenario's `[run.mission_params]` table.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, MutableMapping
from dataclasses import dataclass

import msgspec
import numpy as np

from common.config.errors import ConfigValueError
from common.config.loader import build
from common.config.missions import MISSIONS_ENV, add_mission
from common.config.scenario import Scenario
from common.messages import NavFix, StateEstimate, TruthState, VehicleStatus, VelocityCommand
from common.runtime.model.core import Delivery, Emit, QueuePolicy, ServiceCore
from common.runtime.model.dataflow import CoreContext, Dataflow, Input, Output, Service
from common.runtime.model.record import Record, trajectory_sha256

_COV = tuple(0.0 for _ in range(25))


class LoopMetrics(msgspec.Struct, kw_only=True, frozen=True):
    """The test loop's metrics: where the plant ended, how far from its set-point."""

    final_x: float | None
    final_error: float | None
    trajectory_sha256: str


# the mission's registered name and import target (common/config/missions.py)
NAME, TARGET = "testloop", "tests.helpers.testloop:TestLoop"


def missions_env(environ: Mapping[str, str]) -> tuple[str, str]:
    """(variable, value) of the environment that registers the loop as mission NAME beside
    what `environ` registers: set it, and this process and those it starts know the mission."""
    return MISSIONS_ENV, add_mission(environ.get(MISSIONS_ENV, ""), NAME, TARGET)


def register(environ: MutableMapping[str, str]) -> None:
    """Register the loop as mission NAME in `environ` (scripts/bench_*.py: `os.environ`)."""
    variable, value = missions_env(environ)
    environ[variable] = value


class Plant:
    """Integrator plant: x' = u, with u the last delivered command (applied at delivery)."""

    def __init__(self, event_driven: bool = False) -> None:
        self.event_driven = event_driven
        self.applied = 0
        self.x, self.u, self.t = 0.0, 0.0, 0.0

    def _advance(self, t: float) -> None:
        if t > self.t:
            self.x += self.u * (t - self.t)
            self.t = t

    def deliver(self, d: Delivery) -> list[Emit]:
        assert isinstance(d.msg, VelocityCommand)
        self._advance(d.t)
        self.u = d.msg.v
        self.applied += 1
        if not self.event_driven:
            return []
        # the command's age when applied = sensor sample to actuation (stamps are propagated)
        return [
            Emit(
                stream="status",
                msg=VehicleStatus(
                    stamp=d.t,
                    mode="RUN",
                    v_applied=self.u,
                    w_applied=0.0,
                    command_age=max(0.0, d.t - d.msg.stamp),
                    commands_applied=self.applied,
                    commands_rejected=0,
                    commands_clamped=0,
                ),
            )
        ]

    def step(self, t: float) -> list[Emit]:
        self._advance(t)
        return [
            Emit(
                stream="truth", msg=TruthState(stamp=t, x=self.x, y=0.0, theta=0.0, v=self.u, w=0.0)
            )
        ]


class Sensor:
    """Samples the newest truth with seeded Gaussian noise."""

    def __init__(self, rng: np.random.Generator, stamp_at_step: bool = False) -> None:
        self.stamp_at_step = stamp_at_step
        self.rng = rng
        self.last: TruthState | None = None

    def deliver(self, d: Delivery) -> list[Emit]:
        assert isinstance(d.msg, TruthState)
        self.last = d.msg
        return []

    def step(self, t: float) -> list[Emit]:
        if self.last is None:
            return []
        z = self.last.x + float(self.rng.normal(0.0, 0.2))
        stamp = t if self.stamp_at_step else self.last.stamp
        return [
            Emit(
                stream="nav",
                msg=NavFix(
                    stamp=stamp,
                    x=z,
                    y=0.0,
                    heading=0.0,
                    speed=0.0,
                    std_xy=0.2,
                    std_heading=0.0,
                    std_speed=0.0,
                ),
            )
        ]


class Filter:
    """First-order lag on the fixes (eq. 3 of the paper), published every period."""

    def __init__(self, event_driven: bool = False) -> None:
        self.event_driven = event_driven
        self.stamp = 0.0
        self.x: float | None = None

    def deliver(self, d: Delivery) -> list[Emit]:
        assert isinstance(d.msg, NavFix)
        # eq. (3): u_i = (dt e_i + T u_{i-1}) / (dt + T), dt = 0.1, T = 0.2
        self.x = d.msg.x if self.x is None else (0.1 * d.msg.x + 0.2 * self.x) / 0.3
        self.stamp = d.msg.stamp
        return self._emit(self.stamp) if self.event_driven else []

    def _emit(self, stamp: float) -> list[Emit]:
        if self.x is None:
            return []
        return [
            Emit(
                stream="state",
                msg=StateEstimate(
                    stamp=stamp, x=self.x, y=0.0, theta=0.0, v=0.0, w=0.0, covariance=_COV
                ),
            )
        ]

    def step(self, t: float) -> list[Emit]:
        return [] if self.event_driven else self._emit(t)


class Controller:
    """Proportional controller towards the set-point."""

    def __init__(self, setpoint: float, event_driven: bool = False) -> None:
        self.setpoint = setpoint
        self.event_driven = event_driven
        self.stamp = 0.0
        self.x: float | None = None

    def deliver(self, d: Delivery) -> list[Emit]:
        assert isinstance(d.msg, StateEstimate)
        self.x = d.msg.x
        self.stamp = d.msg.stamp
        return self._command(self.stamp) if self.event_driven else []

    def _command(self, stamp: float) -> list[Emit]:
        if self.x is None:
            return []
        u = max(-2.0, min(2.0, 0.8 * (self.setpoint - self.x)))
        return [Emit(stream="cmd", msg=VelocityCommand(stamp=stamp, v=u, w=0.0, path_id=0))]

    def step(self, t: float) -> list[Emit]:
        return [] if self.event_driven else self._command(t)


class _Crashing:
    """Wraps a core so its process dies at a given time (fault injection for tests)."""

    def __init__(self, core: ServiceCore, at_s: float) -> None:
        self.core, self.at_s = core, at_s

    def deliver(self, d: Delivery) -> list[Emit]:
        return self.core.deliver(d)

    def step(self, t: float) -> list[Emit]:
        if t >= self.at_s:
            os._exit(3)  # a hard death, as a segfault or the OOM killer would cause
        return self.core.step(t)


@dataclass(frozen=True, kw_only=True)
class TestLoopParams:
    """The toy loop's `[run.mission_params]`: set-point and fault injection."""

    __test__ = False  # not a pytest class

    setpoint: float = 10.0
    # event-driven: filter and controller react to each delivery at once (wake inputs) and
    # the plant reports each command's age on arrival, for latency benchmarks
    event_driven: bool = False
    crash_service: str = ""  # this service's process exits with code 3 at crash_at_s ...
    crash_at_s: float = 0.0  # ... so tests can check that a dead service fails the run fast

    def __post_init__(self) -> None:
        if self.crash_service and self.crash_service not in ("ctrl", "filter", "plant", "sensor"):
            raise ConfigValueError("crash_service", "must be one of ctrl, filter, plant, sensor")

    @classmethod
    def of(cls, scenario: Scenario) -> TestLoopParams:
        return build(cls, dict(scenario.run.mission_params), path=("run", "mission_params"))


def _crashing(name: str, core: ServiceCore, p: TestLoopParams) -> ServiceCore:
    return _Crashing(core, p.crash_at_s) if name == p.crash_service else core


def _plant(ctx: CoreContext) -> ServiceCore:
    p = TestLoopParams.of(ctx.scenario)
    return _crashing(ctx.service, Plant(p.event_driven), p)


def _sensor(ctx: CoreContext) -> ServiceCore:
    p = TestLoopParams.of(ctx.scenario)
    return _crashing(ctx.service, Sensor(ctx.rng, stamp_at_step=p.event_driven), p)


def _filter(ctx: CoreContext) -> ServiceCore:
    p = TestLoopParams.of(ctx.scenario)
    return _crashing(ctx.service, Filter(p.event_driven), p)


def _ctrl(ctx: CoreContext) -> ServiceCore:
    p = TestLoopParams.of(ctx.scenario)
    return _crashing(ctx.service, Controller(p.setpoint, p.event_driven), p)


def testloop_dataflow(p: TestLoopParams) -> Dataflow:
    """sensor -> filter -> ctrl -> plant -> (truth) -> sensor; wake inputs when event-driven."""
    ev = p.event_driven
    return Dataflow.declare(
        Service(
            name="plant",
            factory=_plant,
            period_s=0.05,
            inputs=(Input(source="ctrl", stream="cmd", msg_type=VelocityCommand, wake=ev),),
            outputs=(
                Output(stream="truth", msg_type=TruthState),
                Output(stream="status", msg_type=VehicleStatus),
            ),
        ),
        Service(
            name="sensor",
            factory=_sensor,
            period_s=0.1,
            inputs=(
                Input(
                    source="plant", stream="truth", msg_type=TruthState, policy=QueuePolicy.NEWEST
                ),
            ),
            outputs=(Output(stream="nav", msg_type=NavFix),),
        ),
        Service(
            name="filter",
            factory=_filter,
            period_s=0.1,
            inputs=(Input(source="sensor", stream="nav", msg_type=NavFix, wake=ev),),
            outputs=(Output(stream="state", msg_type=StateEstimate),),
        ),
        Service(
            name="ctrl",
            factory=_ctrl,
            period_s=0.1,
            offset_s=0.05,
            inputs=(
                Input(
                    source="filter",
                    stream="state",
                    msg_type=StateEstimate,
                    policy=QueuePolicy.NEWEST,
                    wake=ev,
                ),
            ),
            outputs=(Output(stream="cmd", msg_type=VelocityCommand),),
        ),
    )


class TestLoop:
    """The toy mission: runs to max_time_s; metrics are the final error and the hash."""

    __test__ = False  # not a pytest class
    preload = ()  # its cores are in its own module (the fork server imports it)

    def __init__(self, scenario: Scenario) -> None:
        self.max_time_s: float = scenario.run.max_time_s
        self.params = TestLoopParams.of(scenario)
        self.dataflow = testloop_dataflow(self.params)

    def observe(self, record: Record) -> str | None:
        return None  # runs to max_time_s

    def ends_on(self, service: str, stream: str) -> bool:
        return False  # observe looks at nothing

    def metrics(self, record: Record) -> LoopMetrics:
        truth = [m for m in record.stream("plant", "truth") if isinstance(m, TruthState)]
        sp = self.params.setpoint
        return LoopMetrics(
            final_x=truth[-1].x if truth else None,
            final_error=abs(sp - truth[-1].x) if truth else None,
            trajectory_sha256=trajectory_sha256(truth),
        )
