"""The declared dataflow of a mission: its services, their typed inputs and outputs, and links.

A mission states its whole graph once, as data (the way a dora dataflow file or a ros2 launch
description does): each service's name, core factory, step period (or none: event-driven),
the inputs it reads (which service's stream, of which message type, with which queue policy)
and the outputs it publishes. Every runtime wires from this declaration; it is validated
before anything runs, and a running mission serves it on the bus (Keys.dataflow) so a remote
tool learns a run's streams and message types without the scenario file.
"""

from __future__ import annotations

import hashlib
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import TYPE_CHECKING, TypedDict

import msgspec
import numpy as np

from common.messages import Message
from common.runtime.model.core import QueuePolicy, ServiceCore

if TYPE_CHECKING:
    from common.config.scenario import Scenario


# a fleet's services are named "<vehicle id>.<service>" (services/mission/fleet.py)
FLEET_SEP = "."


def qualified(vehicle: str, service: str) -> str:
    """The name of one fleet vehicle's service, e.g. ("auv2", "planner") -> "auv2.planner"."""
    return f"{vehicle}{FLEET_SEP}{service}"


def vehicle_of(service: str) -> str:
    """The fleet vehicle a service belongs to ("auv2.planner" -> "auv2"); "" outside a fleet."""
    return service.rpartition(FLEET_SEP)[0]


class DataflowError(ValueError):
    """The declared inputs and outputs of the services do not fit together."""


@dataclass(frozen=True, kw_only=True)
class Input:
    """One declared input: which service's stream, of which message type, with which policy."""

    source: str  # publishing service name, e.g. "sensor"
    stream: str  # stream name, e.g. "nav"
    msg_type: type[Message]
    policy: QueuePolicy = QueuePolicy.ALL
    # wake=True asks the runtime to call the core at the delivery time itself (an event);
    # otherwise deliveries are handed over just before the next periodic step.
    wake: bool = False
    # deliveries held for the core at most (in flight on the modelled link, or waiting for
    # the step); beyond it the oldest are dropped and counted, so a flood costs neither
    # memory nor a step's time without bound. A normal run holds a handful.
    max_queued: int = 64
    # a simulation tap: an ideal link (no modelled fault), read by the host for the link
    # model's ranges (the vehicle's true position, common/netmodel/network.py), never seen
    # by the core. Only placement adds taps, so a scenario without one declares none.
    tap: bool = False


@dataclass(frozen=True, kw_only=True)
class Output:
    """One declared output stream of a service."""

    stream: str
    msg_type: type[Message]


@dataclass(frozen=True, kw_only=True)
class CoreContext:
    """What a core factory is given; each factory takes from it only what its core needs."""

    scenario: Scenario
    service: str  # the service's name in the dataflow

    @cached_property
    def rng(self) -> np.random.Generator:
        """The service's own generator, keyed by (seed, service name): independent, reproducible."""
        h = hashlib.blake2b(self.service.encode(), digest_size=8).digest()
        return np.random.default_rng([self.scenario.run.seed, int.from_bytes(h, "little")])

    def sibling(self, name: str) -> str:
        """The name of service `name` of this service's own vehicle: "auv2.vehicle" beside
        "auv2.sensor" in a fleet, `name` itself otherwise."""
        vehicle = vehicle_of(self.service)
        return qualified(vehicle, name) if vehicle else name


CoreFactory = Callable[[CoreContext], ServiceCore]


class InputDescription(TypedDict):
    """An Input as Dataflow.describe() gives it: its message type and policy by name."""

    source: str
    stream: str
    type: str
    policy: str  # a QueuePolicy's value
    wake: bool
    max_queued: int


class OutputDescription(TypedDict):
    """An Output as Dataflow.describe() gives it."""

    stream: str
    type: str


class ServiceDescription(TypedDict):
    """A Service as Dataflow.describe() gives it (no factory: plain data)."""

    name: str
    period_s: float | None
    offset_s: float
    inputs: list[InputDescription]
    outputs: list[OutputDescription]


class DataflowDescription(TypedDict):
    """Dataflow.describe(): the declaration as JSON-ready data, what a running mission serves
    on Keys.dataflow; `links` by name (source/stream->receiver)."""

    services: list[ServiceDescription]
    links: list[str]


def read_description(data: object) -> DataflowDescription:
    """A described dataflow as it came (a live run's reply, parsed JSON), checked;
    msgspec.ValidationError (a ValueError) says what does not fit."""
    return msgspec.convert(data, DataflowDescription)


@dataclass(frozen=True, kw_only=True)
class Service:
    """One service of the dataflow: its core factory, period and typed inputs and outputs."""

    name: str
    factory: CoreFactory
    inputs: tuple[Input, ...] = ()
    outputs: tuple[Output, ...] = ()
    # seconds between steps; None: event-driven (steps only on deliveries to wake inputs)
    period_s: float | None = 0.1
    offset_s: float = 0.0  # first step at offset_s, then every period_s

    def make_core(self, scenario: Scenario) -> ServiceCore:
        return self.factory(CoreContext(scenario=scenario, service=self.name))


@dataclass(frozen=True, kw_only=True)
class Link:
    """One edge of the graph: an output stream of `source` read by `receiver`."""

    source: str
    stream: str
    receiver: str
    input: Input

    @property
    def name(self) -> str:
        """The link's name in network profiles and statistics: 'source/stream->receiver'."""
        return f"{self.source}/{self.stream}->{self.receiver}"


@dataclass(frozen=True)
class Dataflow:
    """A validated dataflow: the services by name and, per (source, stream), its receivers."""

    services: dict[str, Service]
    receivers: dict[tuple[str, str], tuple[tuple[str, Input], ...]] = field(repr=False)

    @classmethod
    def declare(cls, *services: Service) -> Dataflow:
        """Check the declaration (unique names, positive periods, every input fed by an output
        of the same message type) and index it; DataflowError names the first problem."""
        by_name: dict[str, Service] = {}
        for s in services:
            if s.name in by_name:
                raise DataflowError(f"two services are named {s.name!r}")
            if s.period_s is not None and s.period_s <= 0:
                raise DataflowError(f"{s.name}: period_s must be > 0 (or None: event-driven)")
            if s.period_s is None and not any(i.wake for i in s.inputs):
                raise DataflowError(f"{s.name}: an event-driven service needs a wake input")
            if any(i.max_queued < 1 for i in s.inputs):
                raise DataflowError(f"{s.name}: an input's max_queued must be >= 1")
            streams = [o.stream for o in s.outputs]
            if len(set(streams)) != len(streams):
                raise DataflowError(f"{s.name}: an output stream is declared twice")
            by_name[s.name] = s
        outputs = {(s.name, o.stream): o for s in services for o in s.outputs}
        receivers: dict[tuple[str, str], list[tuple[str, Input]]] = {k: [] for k in outputs}
        for s in sorted(services, key=lambda s: s.name):
            for i in s.inputs:
                out = outputs.get((i.source, i.stream))
                if out is None:
                    raise DataflowError(
                        f"{s.name}: input {i.source}/{i.stream} is not an output of any service"
                    )
                if out.msg_type is not i.msg_type:
                    raise DataflowError(
                        f"{s.name}: input {i.source}/{i.stream} expects {i.msg_type.__name__}"
                        f" but {i.source} publishes {out.msg_type.__name__}"
                    )
                receivers[(i.source, i.stream)].append((s.name, i))
        return cls(dict(sorted(by_name.items())), {k: tuple(v) for k, v in receivers.items()})

    @property
    def names(self) -> tuple[str, ...]:
        """Service names, sorted (the order every runtime uses)."""
        return tuple(self.services)

    def service(self, name: str) -> Service:
        """The declaration of one service; ValueError naming the services there are."""
        try:
            return self.services[name]
        except KeyError:
            raise ValueError(
                f"unknown service {name!r}; this mission has {', '.join(self.names)}"
            ) from None

    @property
    def links(self) -> tuple[Link, ...]:
        """Every edge, in (source, stream, receiver) order."""
        return tuple(
            Link(source=src, stream=stream, receiver=rcv, input=i)
            for (src, stream), rs in sorted(self.receivers.items())
            for rcv, i in rs
        )

    def describe(self) -> DataflowDescription:
        """The declaration as plain data (JSON-ready): what a running mission serves."""
        return {
            "services": [
                {
                    "name": s.name,
                    "period_s": s.period_s,
                    "offset_s": s.offset_s,
                    "inputs": [
                        {
                            "source": i.source,
                            "stream": i.stream,
                            "type": i.msg_type.__name__,
                            "policy": i.policy.value,
                            "wake": i.wake,
                            "max_queued": i.max_queued,
                        }
                        for i in s.inputs
                    ],
                    "outputs": [
                        {"stream": o.stream, "type": o.msg_type.__name__} for o in s.outputs
                    ],
                }
                for s in self.services.values()
            ],
            "links": [lk.name for lk in self.links],
        }
