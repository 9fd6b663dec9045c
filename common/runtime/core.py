"""The pure service-core contract every runtime hosts (inproc, lockstep, realtime)."""

from __future__ import annotations

from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol, runtime_checkable

from common.messages import Message


class QueuePolicy(Enum):
    """How a runtime queues deliveries of one input between two steps of its core."""

    ALL = "all"  # every delivered message is handed to the core, in delivery order
    NEWEST = "newest"  # only the newest delivery since the last step (control-loop inputs)


@dataclass(frozen=True, kw_only=True)
class InputSpec:
    """One declared input: which service's stream, of which message type, with which policy."""

    source: str  # publishing service name, e.g. "sensor"
    stream: str  # stream name, e.g. "nav"
    msg_type: type[Message]
    policy: QueuePolicy = QueuePolicy.ALL
    # wake=True asks the runtime to call the core at the delivery time itself (an event);
    # otherwise deliveries are handed over just before the next periodic step.
    wake: bool = False


@dataclass(frozen=True, kw_only=True)
class OutputSpec:
    """One declared output stream of a core."""

    stream: str
    msg_type: type[Message]


@dataclass(frozen=True, kw_only=True)
class CoreSpec:
    """What a core declares to its runtime: name, inputs, outputs and step period."""

    name: str
    inputs: tuple[InputSpec, ...] = ()
    outputs: tuple[OutputSpec, ...] = ()
    period_s: float = 0.1
    offset_s: float = 0.0  # first step at offset_s, then every period_s


@dataclass(frozen=True, kw_only=True)
class Emit:
    """A message a core asks its runtime to publish on one of its declared output streams."""

    stream: str
    msg: Message


@dataclass
class Delivery:
    """A message handed to a core: the input it arrived on and its modelled delivery time."""

    source: str
    stream: str
    msg: Message
    t: float = field(default=0.0)  # delivery time (s, runtime clock)


@runtime_checkable
class ServiceCore(Protocol):
    """A pure service: no Zenoh, no threads, no wall clock, no global RNG.

    The runtime calls `deliver` for every delivered message in delivery order (time, source,
    stream, seq), then `step(t)` at each period. Both may return messages to publish; `step`
    is where periodic outputs are produced. Time `t` is seconds on the runtime's clock.
    """

    spec: CoreSpec

    def deliver(self, d: Delivery) -> list[Emit]: ...

    def step(self, t: float) -> list[Emit]: ...
