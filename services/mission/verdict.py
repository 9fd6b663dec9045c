"""A run's verdict from its metrics: failed (and why), or fell behind its clock (and why)."""

from __future__ import annotations

from typing import Any

from services.mission.outcome import describe, outcome_of

# several services silent this long in all: the run's timing was not the scenario's
BEHIND_S = 2.0


def verdict(metrics: dict[str, Any]) -> tuple[bool, str] | None:
    """(succeeded, the outcome in words) of a run its mission judged; None if it does not
    judge or the run was interrupted."""
    outcome = outcome_of(metrics)
    if outcome is None or metrics.get("end_reason") == "interrupted":
        return None
    return outcome == "success", describe(metrics)


def mission_failure(metrics: dict[str, Any]) -> str | None:
    """Why a run that ended is no success ("mission failed: " and its outcome in words), or
    None: it succeeded, it was interrupted (not a judgment), or its mission does not judge
    success (no `outcome` or `success`)."""
    judged = verdict(metrics)
    if judged is None or judged[0]:
        return None
    return "mission failed: " + judged[1]


def fell_behind(metrics: dict[str, Any]) -> str | None:
    """Why a realtime run's outcome may say little of its method: several services fell
    silent (unresponsive_s) for seconds, which is the machine not keeping up with the clock
    or the launcher cut off from them; one frozen service is the alarms' business."""
    silent = {k: float(v) for k, v in (metrics.get("unresponsive_s") or {}).items() if v}
    total = sum(silent.values())
    if metrics.get("runtime") != "realtime" or len(silent) < 2 or total < BEHIND_S:
        return None
    worst = max(silent, key=lambda k: silent[k])
    return (
        f"{len(silent)} services fell silent for {total:.1f} s of mission time in all "
        f"(the most: {worst}, {silent[worst]:.1f} s): this machine did not keep up with the "
        "run's time scale, or the network to them was out; the outcome is that of a late "
        "loop. A lower --time-scale, or the services spread over more hosts, keeps its timing."
    )
