"""When a service went silent: gaps in what it publishes longer than a few of its periods.

A frozen process (SIGSTOP, a debugger, a swapped-out host) keeps its liveliness token and its
TCP connection, so nothing else notices; but a periodic service publishes at least its stats
every `runtime.stats_period_s`, so a long enough gap in everything it sent is proof. The same
rule serves the launcher's live alarm (SilenceWatch) and the run's metrics (unresponsive_s).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import pairwise

from common.messages import Message
from common.runtime.model.dataflow import Dataflow
from common.runtime.model.record import Record

SILENT_PERIODS = 3.0  # gaps of this many periods: one late message is not an alarm


def thresholds(flow: Dataflow, stats_period_s: float) -> dict[str, float]:
    """Per periodic service, the silence (mission seconds) that means it is unresponsive;
    event-driven services (period None) may rightly stay quiet and are not judged."""
    return {
        name: SILENT_PERIODS * max(svc.period_s, stats_period_s)
        for name, svc in flow.services.items()
        if svc.period_s is not None
    }


def sent_at(msg: Message) -> float:
    """When a message was published (mission time): its envelope's `sent`, else its stamp."""
    return msg.sent if msg.sent > 0.0 else msg.stamp


def unresponsive_s(record: Record, limits: dict[str, float], t_end: float) -> dict[str, float]:
    """Per judged service, the mission time it spent silent beyond its limit (a gap of g
    seconds over a limit L counts g - L: the time it was overdue), the end of the run
    included. 0.0 for a service that never fell silent."""
    heard: dict[str, list[float]] = {name: [] for name in limits}
    for service, stream in record.keys():
        if service in heard:
            heard[service].extend(sent_at(m) for m in record.stream(service, stream))
    out = {}
    for name, limit in limits.items():
        edges = [0.0, *sorted(heard[name]), t_end]  # silent from the start counts too
        out[name] = round(sum(max(0.0, b - a - limit) for a, b in pairwise(edges)), 3)
    return out


@dataclass
class SilenceWatch:
    """The live form: told what each service published and the mission time, it says when a
    service falls silent and when it speaks again (one line each)."""

    limits: dict[str, float]
    last: dict[str, float] = field(default_factory=dict)
    silent: set[str] = field(default_factory=set)

    def heard(self, service: str, msg: Message) -> str | None:
        """Take one message; a line when its service was silent until now."""
        if service not in self.limits:
            return None
        t = sent_at(msg)
        before = self.last.get(service)
        self.last[service] = t if before is None else max(before, t)
        if service in self.silent:
            self.silent.discard(service)
            gap = t - (before or 0.0)
            return f"{service} responsive again at t={t:.2f} s (silent {gap:.1f} s)"
        return None

    def check(self, t_now: float) -> list[str]:
        """Lines for the services that have just exceeded their silence limit."""
        lines = []
        for service, limit in self.limits.items():
            t = self.last.get(service, 0.0)  # one that never spoke: silent since the start
            if service not in self.silent and t_now - t > limit:
                self.silent.add(service)
                lines.append(
                    f"ALARM: {service} unresponsive since t={t:.2f} s (nothing published for "
                    f"{t_now - t:.1f} s)"
                )
        return lines
