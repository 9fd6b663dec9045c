"""A run's verdict from its metrics: failed (and why), or fell behind its clock (and why)."""

from __future__ import annotations

from typing import Any

from common.runtime.metrics_record import RunMetrics
from services.mission.outcome import describe
from services.mission.records import auv_metrics

# several services silent this long in all: the run's timing was not the scenario's
BEHIND_S = 2.0


def verdict(metrics: RunMetrics[Any]) -> tuple[bool, str] | None:
    """(succeeded, the outcome in words) of a run its mission judged; None if it does not
    judge (a mission other than the AUV's) or the run was interrupted."""
    mission = auv_metrics(metrics)
    if mission is None or metrics.facts.end_reason == "interrupted":
        return None
    return mission.outcome == "success", describe(mission, metrics.facts)


def mission_failure(metrics: RunMetrics[Any]) -> str | None:
    """Why a run that ended is no success ("mission failed: " and its outcome in words), or
    None: it succeeded, it was interrupted (not a judgment), or its mission does not judge
    success."""
    judged = verdict(metrics)
    if judged is None or judged[0]:
        return None
    return "mission failed: " + judged[1]


def fell_behind(metrics: RunMetrics[Any]) -> str | None:
    """Why a realtime run's outcome may say little of its method: several services fell
    silent (unresponsive_s) for seconds, which is the machine not keeping up with the clock
    or the launcher cut off from them; one frozen service is the alarms' business."""
    facts = metrics.facts
    silent = {k: v for k, v in facts.unresponsive_s.items() if v}
    total = sum(silent.values())
    if facts.runtime != "realtime" or len(silent) < 2 or total < BEHIND_S:
        return None
    worst = max(silent, key=lambda k: silent[k])
    return (
        f"{len(silent)} services fell silent for {total:.1f} s of mission time in all "
        f"(the most: {worst}, {silent[worst]:.1f} s): this machine did not keep up with the "
        "run's time scale, or the network to them was out; the outcome is that of a late "
        "loop. A lower --time-scale, or the services spread over more hosts, keeps its timing."
    )
