"""The outcome of one run, whatever runtime produced it."""

from __future__ import annotations

from dataclasses import dataclass

import msgspec

from common.runtime.model.record import Record


@dataclass
class RunResult:
    """Why a run ended, at what virtual time, after how many ticks, its record and metrics;
    `failure` says what failed when a process did (reason "service_failed"; in a fleet's
    realtime run, which services were lost while the rest went on, whatever the reason)."""

    reason: str
    t_end: float
    ticks: int
    record: Record
    metrics: msgspec.Struct  # the mission's (Mission.metrics)
    failure: str = ""
