"""What a run's outcome is (success, rho0 breach, collision, goal not reached), and in words.

Precedence, strongest first: any contact with an obstacle is a "collision", whatever else
happened; a run without contact that did not reach the goal is "not_reached" (whether it also
came inside rho0 is said in its words); a run that reached the goal without contact but came
inside the safety distance rho0 of eq. (6) at any moment is a "rho0_breach"; only a run that
reached the goal and never came inside rho0 is a "success".
"""

from __future__ import annotations

import math
from typing import Any, Literal, cast

Outcome = Literal["success", "rho0_breach", "collision", "not_reached"]
OUTCOMES: tuple[Outcome, ...] = ("success", "rho0_breach", "collision", "not_reached")


def classify(*, reached_goal: bool, contact: bool, below_rho0: bool) -> Outcome:
    """The outcome of a run, by the precedence of the module docstring."""
    if contact:
        return "collision"
    if not reached_goal:
        return "not_reached"
    return "rho0_breach" if below_rho0 else "success"


def outcome_of(m: dict[str, Any]) -> Outcome | None:
    """The outcome a run's metrics state (derived for metrics older than `outcome` from
    `success` and what it was made of); None if its mission does not judge runs."""
    stated = m.get("outcome")
    if stated in OUTCOMES:
        return cast(Outcome, stated)
    if "success" not in m:
        return None
    if m["success"]:
        return "success"
    contact = bool(m.get("collisions")) or m.get("first_contact_t_s") is not None
    # no contact and at the goal, yet no success: only the safety distance is left
    return classify(reached_goal=bool(m.get("reached_goal")), contact=contact, below_rho0=True)


def _num(m: dict[str, Any], key: str, default: float = float("nan")) -> float:
    """A numeric metric, `default` when missing or null (a run cut short has no value)."""
    v = m.get(key)
    return default if v is None else float(v)


def describe(m: dict[str, Any]) -> str:
    """The outcome in words, e.g. "goal reached, but 0.33 m inside the safety distance rho0
    = 1.0 m for 2.1 s (min clearance 0.67 m)"; "" if the mission does not judge runs."""
    outcome = outcome_of(m)
    if outcome is None:
        return ""
    if outcome == "success":
        rho0 = m.get("rho0_m")
        kept = "" if rho0 is None else f", never inside the safety distance rho0 = {float(rho0)} m"
        return f"goal reached in {_num(m, 'travel_time_s', 0.0):.2f} s{kept}{_closest(m)}"
    if outcome == "rho0_breach":
        return "goal reached, but " + _inside_rho0(m)
    why = []
    hulls = outcome == "collision" and (m.get("vehicle_collisions") or 0) > 0
    if hulls:  # two vehicles of a fleet touched: the closest pair did
        pair = str(m.get("min_separation_pair") or "two vehicles").replace("-", " and ")
        why.append(f"{pair} in contact (hull to hull {_num(m, 'min_separation_m'):.2f} m)")
    if outcome == "collision" and (not hulls or (m.get("collisions") or 0) > 0):
        first = m.get("first_contact_t_s")
        contact = f"contact at t={first:.2f} s " if first is not None else "contact "
        contact += f"(min clearance {_num(m, 'min_clearance_m'):.3g} m)"
        if m.get("time_in_contact_s") is not None:
            contact += f", in contact for {m['time_in_contact_s']:.2f} s"
        why.append(contact)
    if not m.get("reached_goal"):
        where = m.get("final_distance_to_goal_m")
        far = "" if where is None else f", {where:.1f} m from the goal"
        t_end = m.get("t_end_s") or 0.0
        why.append(f"goal not reached ({m.get('end_reason')} at t={t_end:.2f} s{far})")
    elif outcome == "collision":
        why.append("goal reached")
    if outcome == "not_reached" and (m.get("rho0_breach_m") or 0.0) > 0.0:
        why.append(_inside_rho0(m))
    return "; ".join(why)


def _closest(m: dict[str, Any]) -> str:
    """ " (min clearance 1.17 m, min separation 5.03 m)": the nearest an obstacle came (none
    in an empty world) and, in a fleet, the nearest two hulls came."""
    near = [
        f"{words} {v:.2f} m"
        for key, words in (
            ("min_clearance_m", "min clearance"),
            ("min_separation_m", "min separation"),
        )
        if math.isfinite(v := _num(m, key))
    ]
    return f" ({', '.join(near)})" if near else ""


def _inside_rho0(m: dict[str, Any]) -> str:
    """How deep inside rho0, for how long; a fleet's deepest breach in its own terms: one
    vehicle's of an obstacle, or a pair's of each other (fleet_metrics.py)."""
    who = m.get("rho0_breach_by") or ""
    vehicles = m.get("vehicles") or {}
    if who in vehicles:
        return f"{who} came " + _inside_rho0(vehicles[who])
    rho0 = m.get("rho0_m")
    what = "the safety distance" + ("" if rho0 is None else f" rho0 = {float(rho0)} m")
    if who:  # two vehicles: the distance is hull to hull
        gap = _num(m, "rho0_m") - _num(m, "rho0_breach_m")
        return (
            f"{who.replace('-', ' and ')} came {_num(m, 'rho0_breach_m'):.2f} m inside {what} "
            f"of each other for {_num(m, 'time_below_rho0_s', 0.0):.1f} s "
            f"(hull to hull {gap:.2f} m)"
        )
    return (
        f"{_num(m, 'rho0_breach_m'):.2f} m inside {what} for "
        f"{_num(m, 'time_below_rho0_s', 0.0):.1f} s "
        f"(min clearance {_num(m, 'min_clearance_m'):.2f} m)"
    )
