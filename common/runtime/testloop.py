"""A small closed loop of toy cores (sensor, filter, P controller, integrator plant).

It exercises the runtimes end to end without the AUV services: a noisy sensor samples the
plant, a filter smooths it, a proportional controller drives the plant to a set-point, the
plant integrates the command. Select it with `[run] mission = "common.runtime.testloop:TestLoop"`.
"""

from __future__ import annotations

import hashlib
import os
from typing import Any

import numpy as np

from common.messages import NavFix, StateEstimate, TruthState, VehicleStatus, VelocityCommand
from common.runtime.core import CoreSpec, Delivery, Emit, InputSpec, OutputSpec, QueuePolicy
from common.runtime.record import Record, trajectory_sha256

_COV = tuple(0.0 for _ in range(25))


class Plant:
    """Integrator plant: x' = u, with u the last delivered command (applied at delivery)."""

    def __init__(self, event_driven: bool = False) -> None:
        self.spec = CoreSpec(
            name="plant",
            inputs=(
                InputSpec(source="ctrl", stream="cmd", msg_type=VelocityCommand, wake=event_driven),
            ),
            outputs=(
                OutputSpec(stream="truth", msg_type=TruthState),
                OutputSpec(stream="status", msg_type=VehicleStatus),
            ),
            period_s=0.05,
        )
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
        self.spec = CoreSpec(
            name="sensor",
            inputs=(
                InputSpec(
                    source="plant", stream="truth", msg_type=TruthState, policy=QueuePolicy.NEWEST
                ),
            ),
            outputs=(OutputSpec(stream="nav", msg_type=NavFix),),
            period_s=0.1,
        )
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
        self.spec = CoreSpec(
            name="filter",
            inputs=(InputSpec(source="sensor", stream="nav", msg_type=NavFix, wake=event_driven),),
            outputs=(OutputSpec(stream="state", msg_type=StateEstimate),),
            period_s=0.1,
        )
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
        self.spec = CoreSpec(
            name="ctrl",
            inputs=(
                InputSpec(
                    source="filter",
                    stream="state",
                    msg_type=StateEstimate,
                    policy=QueuePolicy.NEWEST,
                    wake=event_driven,
                ),
            ),
            outputs=(OutputSpec(stream="cmd", msg_type=VelocityCommand),),
            period_s=0.1,
            offset_s=0.05,
        )
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

    def __init__(self, core: Any, at_s: float) -> None:
        self.core, self.at_s, self.spec = core, at_s, core.spec

    def deliver(self, d: Delivery) -> list[Emit]:
        return self.core.deliver(d)

    def step(self, t: float) -> list[Emit]:
        if t >= self.at_s:
            os._exit(3)  # a hard death, as a segfault or the OOM killer would cause
        return self.core.step(t)


def _rng(seed: int, name: str) -> np.random.Generator:
    h = int.from_bytes(hashlib.blake2b(name.encode(), digest_size=8).digest(), "little")
    return np.random.default_rng([seed, h])


class TestLoop:
    """The toy mission: runs to max_time_s; metrics are the final error and the hash."""

    names = ("ctrl", "filter", "plant", "sensor")
    __test__ = False  # not a pytest class

    def __init__(self, scenario: Any) -> None:
        self.seed: int = scenario.run.seed
        self.max_time_s: float = scenario.run.max_time_s
        self.cfg = scenario.testloop

    def make_core(self, name: str) -> Any:
        ev = self.cfg.event_driven
        makers = {
            "plant": lambda: Plant(ev),
            "filter": lambda: Filter(ev),
            "ctrl": lambda: Controller(self.cfg.setpoint, ev),
            "sensor": lambda: Sensor(_rng(self.seed, "sensor"), stamp_at_step=ev),
        }
        core = makers[name]()
        if name == self.cfg.crash_service:
            core = _Crashing(core, self.cfg.crash_at_s)
        return core

    def observe(self, record: Record) -> str | None:
        return None  # runs to max_time_s

    def metrics(self, record: Record) -> dict[str, Any]:
        truth = [m for m in record.stream("plant", "truth") if isinstance(m, TruthState)]
        return {
            "final_x": truth[-1].x if truth else None,
            "final_error": abs(self.cfg.setpoint - truth[-1].x) if truth else None,
            "trajectory_sha256": trajectory_sha256(truth),
        }
