"""Whether a case passed: the invariants every fault must keep, and the table of outcomes."""

from __future__ import annotations

import math
from typing import Any

from services.chaos.case import Outcome
from services.mission.outcome import describe


def contact(m: dict[str, Any]) -> bool:
    """The hull touched an obstacle (truth) at any time of the run."""
    clearance = m.get("min_clearance_m")
    touched = isinstance(clearance, float | int) and math.isfinite(clearance) and clearance < 0
    return bool(m.get("collisions", 0)) or touched


def succeeded(m: dict[str, Any]) -> bool:
    """The mission's `success` where it judges one (goal reached, no contact, never inside
    the safety distance rho0: services/mission/outcome.py); else reached the goal with no
    contact."""
    if "success" in m:
        return bool(m["success"])
    return bool(m.get("reached_goal")) and not contact(m)


def problems(o: Outcome) -> list[str]:
    """What this case broke; empty when it passed."""
    bad = []
    if o.exit_code is None:
        bad.append("hung")
    if o.leftovers:
        bad.append(f"left running: {', '.join(o.leftovers)}")
    if o.fault.kind == "kill_launcher":
        return bad  # nobody is left to write metrics: that its children went is the test
    m = o.metrics
    if not m:
        bad.append("no metrics.json")
        return bad
    if o.exit_code == 0 and not succeeded(m):
        bad.append("exit 0 without success" + (" (contact)" if contact(m) else ""))
    if o.fault.survivable and not succeeded(m):
        words = describe(m) or (
            f"contact (min clearance {m.get('min_clearance_m'):.2f} m)" if contact(m) else ""
        )
        bad.append(f"mission failed: {m.get('end_reason')}" + (f", {words}" if words else ""))
    if not o.fault.survivable and m.get("end_reason") != "service_failed":
        bad.append(f"end_reason {m.get('end_reason')!r}, expected service_failed")
    return bad


def table(outcomes: list[Outcome]) -> str:
    """fault x outcome, one row per case."""
    head = (
        f"{'fault':<27} {'verdict':<7} {'exit':>4} {'end':<15} {'goal':<5} {'min clr':>8} "
        f"{'hold s':>6} {'fs s':>5} {'left':>4} {'metrics':<7} {'wall s':>6}  why"
    )
    rows = [head, "-" * len(head)]
    for o in outcomes:
        m = o.metrics
        bad = problems(o)
        clr = m.get("min_clearance_m")
        rows.append(
            f"{o.fault.name:<27} {'PASS' if not bad else 'FAIL':<7} "
            f"{'-' if o.exit_code is None else o.exit_code:>4} "
            f"{str(m.get('end_reason', '-'))[:15]:<15} "
            f"{('yes' if m.get('reached_goal') else 'no') if m else '-':<5} "
            f"{f'{clr:.2f}' if isinstance(clr, float | int) else '-':>8} "
            f"{m.get('hold_time_s', 0.0):6.1f} {m.get('failsafe_time_s', 0.0):5.1f} "
            f"{len(o.leftovers):>4} {'yes' if m else 'no':<7} {o.wall_s:6.1f}  "
            + "; ".join(bad or ([o.note] if o.note else []))
        )
    return "\n".join(rows)
