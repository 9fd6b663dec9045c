"""Lockstep look-ahead: which services may start the next tick before the last one is done.

On the default mission the ticks alternate between the vehicle with the sensor and the
estimator, and the vehicle with the planner, whose step (the command sequence) is the long
one: the sensor and the estimator then waited for the planner to finish a tick whose outputs
they never read. A tick's outcome for the coordinator is the services' next needs (from their
acks) and whether the mission ended; both are known before a service has acknowledged when
that service is *predictable*: periodic, with no wake input (its next need is its next step)
and no output to one (it moves no one else's), and publishing nothing the mission's end
depends on (Mission.ends_on). While only predictable services are still running tick k, the
coordinator judges the tick's end on the data it has, works out tick k+1, and sends it at
once to its services: one that none of the other running ones feeds gets it at once (what it
reads from them was all sent before tick k), and if it is still running tick k itself, the
next tick waits in its inbox and it runs it as soon as it acks tick k; one they feed is sent
it as soon as their acks, which carry the frames it reads, are in (lockstep.py). On a tick
whose due services are all predictable (the toy loop's, every one), tick k+1 so goes out with
tick k, and the coordinator's collecting of tick k's acks is off the services' path. The end
of tick k+1 is judged only after tick k's (no data of a later tick can be seen early), so
the trajectory is the same as without look-ahead (and as inproc), bit for bit.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

from common.runtime.model.dataflow import Dataflow
from common.runtime.model.host import STATS_STREAM, to_us
from common.runtime.model.mission import Mission, ends_on


@dataclass(frozen=True)
class Lookahead:
    """What the dataflow and the mission say about starting ticks early (module docstring)."""

    period_us: dict[str, int]  # the predictable services' periods
    feeds: dict[str, frozenset[str]]  # the receivers of each service's streams
    ending: frozenset[str]  # services publishing a stream the mission's end depends on

    @classmethod
    def of(cls, mission: Mission) -> Lookahead:
        flow: Dataflow = mission.dataflow
        feeds: dict[str, set[str]] = {n: set() for n in flow.names}
        wakes: set[str] = set()  # services with an output to someone's wake input
        for (source, _stream), receivers in flow.receivers.items():
            for receiver, spec in receivers:
                feeds[source].add(receiver)
                if spec.wake:
                    wakes.add(source)
        ending = frozenset(
            n
            for n, svc in flow.services.items()
            if any(ends_on(mission, n, s) for s in (*(o.stream for o in svc.outputs), STATS_STREAM))
        )
        period_us = {
            n: to_us(svc.period_s)
            for n, svc in flow.services.items()
            if svc.period_s is not None
            and not any(i.wake for i in svc.inputs)
            and n not in wakes
            and n not in ending
        }
        return cls(period_us, {n: frozenset(r) for n, r in feeds.items()}, ending)

    def predictable(self, running: Iterable[str]) -> bool:
        """Are the tick's outcomes known without these services' acks (module docstring)?"""
        return all(n in self.period_us for n in running)

    def waits(self, due: Sequence[str], running: Sequence[str]) -> dict[str, tuple[str, ...]]:
        """The services of the next tick (`due`), sent it while `running` (predictable, the
        caller's judgement) finish theirs, each with the other running ones it reads: it is
        sent the tick when their acks, with the frames it reads, are in (lockstep.py)."""
        return {s: tuple(r for r in running if r != s and s in self.feeds[r]) for s in due}
