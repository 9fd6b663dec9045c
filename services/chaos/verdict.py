"""Whether a case passed: the invariants every fault must keep, and the table of outcomes."""

from __future__ import annotations

import math

from services.chaos.case import Outcome
from services.chaos.faults import OUTSIDE
from services.mission.outcome import describe
from services.mission.records import AuvMetrics, AuvRun, MissionMetrics, given

# the longest gap (mission seconds) between two of the loop's frames at the launcher, with
# watchers frozen: the vehicle's truth comes every 0.1 s and it holds after 2 s without a
# command; 1 s is a loop that kept its period on a busy machine, not one that stalled
LOOP_GAP_LIMIT_S = 1.0


def contact(m: MissionMetrics) -> bool:
    """The hull touched an obstacle (truth) at any time of the run."""
    clearance = m.min_clearance_m
    touched = isinstance(clearance, float) and math.isfinite(clearance) and clearance < 0
    return given(m.collisions, 0) > 0 or touched


def problems(o: Outcome) -> list[str]:
    """What this case broke; empty when it passed."""
    bad = []
    if o.exit_code is None:
        bad.append("hung")
    if o.leftovers:
        bad.append(f"left running: {', '.join(o.leftovers)}")
    if o.fault.kind == "kill_launcher":
        return bad  # nobody is left to write metrics: that its children went is the test
    if o.metrics is None:
        bad.append("no metrics.json")
        return bad
    m, facts = o.metrics.mission, o.metrics.facts
    if o.exit_code == 0 and not m.success:
        bad.append("exit 0 without success" + (" (contact)" if contact(m) else ""))
    if o.fault.survivable and not m.success:
        words = describe(m, facts) or (
            f"contact (min clearance {given(m.min_clearance_m, math.nan):.2f} m)"
            if contact(m)
            else ""
        )
        bad.append(f"mission failed: {facts.end_reason}" + (f", {words}" if words else ""))
    if not o.fault.survivable and facts.end_reason != "service_failed":
        bad.append(f"end_reason {facts.end_reason!r}, expected service_failed")
    travel, t_end = m.travel_time_s, facts.t_end_s
    if isinstance(travel, float) and isinstance(t_end, float) and travel > t_end:
        bad.append(f"travel time {travel:.2f} s past the run's end t={t_end:.2f} s")
    if o.fault.kind in OUTSIDE:
        bad += outside_problems(o, o.metrics)
    return bad


def outside_problems(o: Outcome, metrics: AuvRun) -> list[str]:
    """What a fault from outside the loop (services/chaos/outside.py) did that it must not."""
    m, x, kind = metrics.mission, o.outside, o.fault.kind
    ran = x.helpers
    bad = [f"{name} hung" for name, r in ran.items() if r.exit is None]
    rejected = (
        given(m.commands_rejected_by_reason, {}) if isinstance(m, AuvMetrics) else dict[str, int]()
    )
    if kind == "watchers":
        held = given(m.hold_time_s, 0.0) + given(m.failsafe_time_s, 0.0)
        if held > 0:
            bad.append(f"the vehicle held {held:.1f} s (HOLD/FAILSAFE)")
        gap = x.loop_gap_s
        if gap is None:
            bad.append("no recording of the launch to time its loop by")
        elif gap > LOOP_GAP_LIMIT_S:
            bad.append(f"the loop stalled {gap:.2f} s (limit {LOOP_GAP_LIMIT_S:g} s)")
        if "lost" not in (ran["record"].stdout if "record" in ran else ""):
            bad.append("the recorder did not say what it lost")
    elif kind == "duplicate":
        dup = ran.get("duplicate")
        if dup is None or dup.exit != 1 or "refused" not in dup.stderr:
            bad.append(f"the duplicate was not refused (exit {dup.exit if dup else None})")
        if not any("a second" in a for a in o.alarms):
            bad.append("no alarm in the launch")
        if rejected.get("out_of_order", 0):
            bad.append(f"{rejected['out_of_order']} commands out of order (interleaved)")
    elif kind == "replay":
        replay = ran.get("replay")
        words = replay.stderr if replay else ""
        code = replay.exit if replay else None
        if code not in (0, 1) or not ("not replaying" in words or "refused" in words):
            bad.append(f"the replay was not kept off the run (exit {code})")
        touched = sum(metrics.facts.record_rejected.values()) + sum(rejected.values())
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
        bad = problems(o)
        m = o.metrics.mission if o.metrics is not None else None
        end = o.metrics.facts.end_reason if o.metrics is not None else "-"
        clr = m.min_clearance_m if m is not None else None
        hold = given(m.hold_time_s, 0.0) if m is not None else 0.0
        failsafe = given(m.failsafe_time_s, 0.0) if m is not None else 0.0
        rows.append(
            f"{o.fault.name:<27} {'PASS' if not bad else 'FAIL':<7} "
            f"{'-' if o.exit_code is None else o.exit_code:>4} "
            f"{end[:15]:<15} "
            f"{('yes' if m.reached_goal else 'no') if m is not None else '-':<5} "
            f"{f'{clr:.2f}' if isinstance(clr, float) else '-':>8} "
            f"{hold:6.1f} {failsafe:5.1f} "
            f"{len(o.leftovers):>4} {'yes' if m is not None else 'no':<7} {o.wall_s:6.1f}  "
            + "; ".join(bad or ([o.note] if o.note else []))
        )
    return "\n".join(rows)
