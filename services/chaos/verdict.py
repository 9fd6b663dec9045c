"""Whether a case passed: the invariants every fault must keep, and the table of outcomes."""

from __future__ import annotations

import math
from typing import Any

from services.chaos.case import Outcome
from services.chaos.faults import OUTSIDE
from services.mission.outcome import describe

# the longest gap (mission seconds) between two of the loop's frames at the launcher, with
# watchers frozen: the vehicle's truth comes every 0.1 s and it holds after 2 s without a
# command; 1 s is a loop that kept its period on a busy machine, not one that stalled
LOOP_GAP_LIMIT_S = 1.0


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
    travel, t_end = m.get("travel_time_s"), m.get("t_end_s")
    if isinstance(travel, float | int) and isinstance(t_end, float | int) and travel > t_end:
        bad.append(f"travel time {travel:.2f} s past the run's end t={t_end:.2f} s")
    if o.fault.kind in OUTSIDE:
        bad += outside_problems(o)
    return bad


def outside_problems(o: Outcome) -> list[str]:
    """What a fault from outside the loop (services/chaos/outside.py) did that it must not."""
    m, x, kind = o.metrics, o.outside, o.fault.kind
    bad = [f"{name} hung" for name, r in x.items() if isinstance(r, dict) and r["exit"] is None]
    rejected = m.get("commands_rejected_by_reason") or {}
    if kind == "watchers":
        held = m.get("hold_time_s", 0.0) + m.get("failsafe_time_s", 0.0)
        if held > 0:
            bad.append(f"the vehicle held {held:.1f} s (HOLD/FAILSAFE)")
        gap = x.get("loop_gap_s")
        if gap is None:
            bad.append("no recording of the launch to time its loop by")
        elif gap > LOOP_GAP_LIMIT_S:
            bad.append(f"the loop stalled {gap:.2f} s (limit {LOOP_GAP_LIMIT_S:g} s)")
        if "lost" not in x.get("record", {}).get("stdout", ""):
            bad.append("the recorder did not say what it lost")
    elif kind == "duplicate":
        dup = x.get("duplicate", {})
        if dup.get("exit") != 1 or "refused" not in dup.get("stderr", ""):
            bad.append(f"the duplicate was not refused (exit {dup.get('exit')})")
        if not any("a second" in a for a in o.alarms):
            bad.append("no alarm in the launch")
        if rejected.get("out_of_order", 0):
            bad.append(f"{rejected['out_of_order']} commands out of order (interleaved)")
    elif kind == "replay":
        replay = x.get("replay", {})
        words = replay.get("stderr", "")
        if replay.get("exit") not in (0, 1) or not ("not replaying" in words or "refused" in words):
            bad.append(f"the replay was not kept off the run (exit {replay.get('exit')})")
        touched = sum((m.get("record_rejected") or {}).values()) + sum(rejected.values())
        if touched:
            bad.append(f"{touched} frames of the replay reached the run (refused by it)")
    elif kind == "forge_tick" and o.injected != 1:
        bad.append("no Tick was forged")
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
