"""The pure service-core contract every runtime hosts (inproc, lockstep, realtime)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from enum import Enum
from typing import Protocol, runtime_checkable

from common.messages import Message


class QueuePolicy(Enum):
    """How a runtime queues deliveries of one input between two steps of its core."""

    ALL = "all"  # every delivered message is handed to the core, in delivery order
    NEWEST = "newest"  # only the newest delivery since the last step (control-loop inputs)


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

    What it reads and writes, and how often it steps, is declared in the mission's dataflow
    (common.runtime.model.dataflow), not by the core. The runtime calls `deliver` for every
    delivered message in delivery order (time, source, stream, seq), then `step(t)` at each
    period. Both may return messages to publish on the service's declared outputs. Time `t`
    is seconds on the runtime's clock.
    """

    def deliver(self, d: Delivery) -> list[Emit]: ...

    def step(self, t: float) -> list[Emit]: ...


@runtime_checkable
class JudgesInputs(Protocol):
    """A core that rejects implausible inputs reports how many, by reason (e.g. 'nav.future');
    its runtime publishes them in the service's statistics."""

    @property
    def inputs_rejected(self) -> Mapping[str, int]: ...


@runtime_checkable
class RestartsFilters(Protocol):
    """A core that restarts a diverged filter reports how often, by filter."""

    @property
    def resets(self) -> Mapping[str, int]: ...


@runtime_checkable
class Prepares(Protocol):
    """A core with work for its next step that needs none of that step's inputs: the runtime
    calls `prepare(t_next)` once the outputs of a step are published (in lockstep, once it has
    acknowledged the tick), so the work is off the path from its inputs to its outputs; the
    next step takes the result only if it runs at t_next. Deterministic in every runtime: it
    sees the core as the step left it, before anything is delivered to the next one."""

    def prepare(self, t_next: float) -> None: ...


@runtime_checkable
class Resumes(Protocol):
    """A core whose state outlives its process: restarted mid-run, it takes up from the
    newest messages its previous process published, by stream (the vehicle's plant: a real
    hull stays where it is while its computer reboots). Returns what it resumed from, for
    the log, or None when nothing it was given lets it resume (it starts over)."""

    def resume(self, own: Mapping[str, Message], t: float) -> str | None: ...


@runtime_checkable
class CountsForStats(Protocol):
    """A core that counts something its run's metrics need (e.g. a fleet planner's steps by
    intent or track per vehicle) reports it by name; its runtime publishes it in the service's
    statistics."""

    @property
    def stats_counters(self) -> Mapping[str, int]: ...
