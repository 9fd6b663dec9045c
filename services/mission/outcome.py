"""What a run's outcome is (success, rho0 breach, collision, goal not reached), and in words.

Precedence, strongest first: any contact with an obstacle is a "collision", whatever else
happened; a run without contact that did not reach the goal is "not_reached" (whether it also
came inside rho0 is said in its words); a run that reached the goal without contact but came
inside the safety distance rho0 of eq. (6) at any moment is a "rho0_breach"; only a run that
reached the goal and never came inside rho0 is a "success".
"""

from __future__ import annotations

import math

from common.runtime.metrics_record import RunFacts
from services.mission.records import (
    OUTCOMES,
    AuvMetrics,
    FleetMetrics,
    MissionMetrics,
    Outcome,
    given,
)

__all__ = ["OUTCOMES", "Outcome", "classify", "describe"]


def classify(*, reached_goal: bool, contact: bool, below_rho0: bool) -> Outcome:
    """The outcome of a run, by the precedence of the module docstring."""
    if contact:
        return "collision"
    if not reached_goal:
        return "not_reached"
    return "rho0_breach" if below_rho0 else "success"


def _num(v: object, default: float = math.nan) -> float:
    """A numeric metric, `default` when absent or null (a run cut short has no value)."""
    return float(v) if isinstance(v, float | int) else default


def describe(m: MissionMetrics, facts: RunFacts) -> str:
    """The outcome in words, e.g. "goal reached, but 0.33 m inside the safety distance rho0
    = 1.0 m for 2.1 s (min clearance 0.67 m)"."""
    if m.outcome == "success":
        kept = f", never inside the safety distance rho0 = {_num(m.rho0_m)} m"
        kept = kept if isinstance(m.rho0_m, float) else ""
        return f"goal reached in {_num(m.travel_time_s, 0.0):.2f} s{kept}{_closest(m)}"
    if m.outcome == "rho0_breach":
        return "goal reached, but " + _inside_rho0(m)
    why = []
    fleet = m if isinstance(m, FleetMetrics) else None
    hulls = m.outcome == "collision" and fleet is not None and fleet.vehicle_collisions > 0
    if hulls and fleet is not None:  # two vehicles of a fleet touched: the closest pair did
        pair = (fleet.min_separation_pair or "two vehicles").replace("-", " and ")
        why.append(f"{pair} in contact (hull to hull {_num(fleet.min_separation_m):.2f} m)")
    if m.outcome == "collision" and (not hulls or given(m.collisions, 0) > 0):
        first = m.first_contact_t_s if isinstance(m, AuvMetrics) else None
        contact = f"contact at t={first:.2f} s " if isinstance(first, float) else "contact "
        contact += f"(min clearance {_num(m.min_clearance_m):.3g} m)"
        if isinstance(m, AuvMetrics) and isinstance(m.time_in_contact_s, float):
            contact += f", in contact for {m.time_in_contact_s:.2f} s"
        why.append(contact)
    if not m.reached_goal:
        where = m.final_distance_to_goal_m if isinstance(m, AuvMetrics) else None
        far = f", {where:.1f} m from the goal" if isinstance(where, float) else ""
        t_end = facts.t_end_s or 0.0
        why.append(f"goal not reached ({facts.end_reason} at t={t_end:.2f} s{far})")
    elif m.outcome == "collision":
        why.append("goal reached")
    if m.outcome == "not_reached" and given(m.rho0_breach_m, 0.0) > 0.0:
        why.append(_inside_rho0(m))
    return "; ".join(why)


def _closest(m: MissionMetrics) -> str:
    """ " (min clearance 1.17 m, min separation 5.03 m)": the nearest an obstacle came (none
    in an empty world) and, in a fleet, the nearest two hulls came."""
    separation = m.min_separation_m if isinstance(m, FleetMetrics) else None
    near = [
        f"{words} {v:.2f} m"
        for value, words in (
            (m.min_clearance_m, "min clearance"),
            (separation, "min separation"),
        )
        if math.isfinite(v := _num(value))
    ]
    return f" ({', '.join(near)})" if near else ""


def _inside_rho0(m: MissionMetrics) -> str:
    """How deep inside rho0, for how long; a fleet's deepest breach in its own terms: one
    vehicle's of an obstacle, or a pair's of each other (fleet_metrics.py)."""
    rho0 = f" rho0 = {_num(m.rho0_m)} m" if isinstance(m.rho0_m, float) else ""
    what = "the safety distance" + rho0
    breach, below = _num(m.rho0_breach_m), _num(m.time_below_rho0_s, 0.0)
    if isinstance(m, FleetMetrics) and m.rho0_breach_by in m.vehicles:
        return f"{m.rho0_breach_by} came " + _inside_rho0(m.vehicles[m.rho0_breach_by])
    if isinstance(m, FleetMetrics) and m.rho0_breach_by:  # two vehicles: hull to hull
        gap = _num(m.rho0_m) - breach
        return (
            f"{m.rho0_breach_by.replace('-', ' and ')} came {breach:.2f} m inside {what} "
            f"of each other for {below:.1f} s (hull to hull {gap:.2f} m)"
        )
    return (
        f"{breach:.2f} m inside {what} for {below:.1f} s "
        f"(min clearance {_num(m.min_clearance_m):.2f} m)"
    )
