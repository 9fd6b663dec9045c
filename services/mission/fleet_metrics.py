"""Metrics of a fleet run: each vehicle's, under its id, and the fleet's (all reached, makespan,
separation between any two hulls, vehicle-vehicle collisions, deconfliction by intent or by
track)."""

from __future__ import annotations

import hashlib
import itertools
import math
from typing import Any, NamedTuple

import numpy as np

from common.config.scenario import Scenario
from common.messages import TruthState
from common.runtime.model.dataflow import qualified
from common.runtime.model.record import Record
from common.world import World
from services.mission.metrics import duration_s, last_counters, mission_metrics
from services.mission.outcome import classify


def fleet_metrics(record: Record, s: Scenario) -> dict[str, Any]:
    """The fleet's metrics; `vehicles` holds each vehicle's (services/mission/metrics.py)."""
    per = {vid: mission_metrics(record, m, World(m.world), vehicle=vid) for vid, m in s.members}
    tallies = {vid: _intent_tallies(record, vid) for vid in per}
    for vid, (by_intent, by_track) in tallies.items():
        per[vid].update(_intent_metrics(by_intent, by_track))
    rho0 = _rho0s(s)
    sep = _separation(fleet_truths(record, s), _radii(s), rho0)
    reached = all(m.get("reached_goal", False) for m in per.values())
    arrivals = [m["travel_time_s"] for m in per.values() if m.get("reached_goal")]
    out: dict[str, Any] = {
        "trajectory_sha256": hashlib.sha256(
            "".join(per[v]["trajectory_sha256"] for v in sorted(per)).encode()
        ).hexdigest(),
        "controller": ",".join(sorted({str(m.get("controller")) for m in per.values()})),
        "fleet_size": len(per),
        "reached_goal": reached,
        "vehicles_reached": len(arrivals),
        "makespan_s": max(arrivals) if reached and arrivals else None,
        # what a run's outcome is told in (services/mission/outcome.py): the last arrival
        "travel_time_s": max(arrivals, default=0.0),
        "min_separation_m": sep["min_separation_m"],
        "min_separation_pair": sep["pair"],
        "min_separation_t_s": sep["closest"].t_s if sep["closest"] is not None else None,
        "vehicle_collisions": sep["collisions"],
        "collisions": sum(int(m.get("collisions", 0)) for m in per.values()),
        "min_clearance_m": min(
            (m["min_clearance_m"] for m in per.values() if "min_clearance_m" in m),
            default=math.nan,
        ),
        **_deepest_breach(per, sep, min(rho0.values())),
        "hold_time_s": sum(float(m.get("hold_time_s", 0.0)) for m in per.values()),
        "failsafe_time_s": sum(float(m.get("failsafe_time_s", 0.0)) for m in per.values()),
        # of every planner step x other vehicle, the share handled by a fresh intent
        "intent_fraction": _share(
            sum(sum(i.values()) for i, _ in tallies.values()),
            sum(sum(k.values()) for _, k in tallies.values()),
        ),
    }
    out["outcome"] = classify(
        reached_goal=reached,
        contact=out["collisions"] > 0 or out["vehicle_collisions"] > 0,
        below_rho0=out["rho0_breach_m"] > 0.0,
    )
    out["success"] = out["outcome"] == "success"
    out["vehicles"] = per
    return out


class Approach(NamedTuple):
    """Where two hulls came closest: the pair, when, how far apart (hull to hull, m) and
    both centres then."""

    a: str
    b: str
    t_s: float
    gap_m: float
    a_xy: tuple[float, float]
    b_xy: tuple[float, float]


def fleet_truths(record: Record, s: Scenario) -> dict[str, np.ndarray]:
    """Each vehicle's true track, (n, 3) rows (t, x, y) from its vehicle's truth stream."""
    return {
        v.id: np.array(
            [
                (q.stamp, q.x, q.y)
                for q in record.stream(qualified(v.id, "vehicle"), "truth")
                if isinstance(q, TruthState)
            ]
        ).reshape(-1, 3)
        for v in s.vehicles
    }


def _radii(s: Scenario) -> dict[str, float]:
    return {v.id: v.vehicle.radius_m for v in s.vehicles}


def _rho0s(s: Scenario) -> dict[str, float]:
    return {v.id: v.planner.rho0_m for v in s.vehicles}


def closest_approach(record: Record, s: Scenario) -> Approach | None:
    """The two hulls of a fleet run that came closest, and where (None: fewer than two
    vehicles with a track); the same comparison as the min_separation_m metric."""
    closest: Approach | None = _separation(fleet_truths(record, s), _radii(s), _rho0s(s))["closest"]
    return closest


def _intent_tallies(record: Record, vid: str) -> tuple[dict[str, int], dict[str, int]]:
    """Vehicle vid's planner's steps by each other vehicle's intent and by its track, from the
    planner's last statistics (services/planner/safety/intent.py: FleetIntents.counters)."""
    counters = last_counters(record, qualified(vid, "planner"))
    by_intent = {k.split(".", 1)[1]: n for k, n in counters.items() if k.startswith("intent.")}
    by_track = {k.split(".", 1)[1]: n for k, n in counters.items() if k.startswith("track.")}
    return by_intent, by_track


def _share(by_intent: int, by_track: int) -> float | None:
    """The share of steps by intent (None without a counted step)."""
    total = by_intent + by_track
    return round(by_intent / total, 4) if total else None


def _intent_metrics(by_intent: dict[str, int], by_track: dict[str, int]) -> dict[str, Any]:
    """intent_fraction (all others together) and, per other vehicle,
    intent_fraction_by_vehicle."""
    others = sorted(set(by_intent) | set(by_track))
    return {
        "intent_fraction": _share(sum(by_intent.values()), sum(by_track.values())),
        "intent_fraction_by_vehicle": {
            o: _share(by_intent.get(o, 0), by_track.get(o, 0)) for o in others
        },
    }


def _deepest_breach(
    per: dict[str, dict[str, Any]], sep: dict[str, Any], least_rho0: float
) -> dict[str, Any]:
    """The deepest way inside a safety distance anyone came, in its own terms: a vehicle
    inside its own rho0 of an obstacle, or two hulls inside the larger of their two rho0
    (each vehicle keeps its own from everything around it); rho0_breach_by names the vehicle
    or the pair ("" without a breach, rho0_m then the least rho0: what every vehicle kept)."""
    depth, rho0_m, below_s, by = 0.0, least_rho0, 0.0, ""
    for vid, m in sorted(per.items()):
        if float(m.get("rho0_breach_m") or 0.0) > depth:
            depth, rho0_m = float(m["rho0_breach_m"]), float(m["rho0_m"])
            below_s, by = float(m.get("time_below_rho0_s") or 0.0), vid
    if sep["breach_m"] > depth:
        depth, rho0_m, below_s, by = (
            sep["breach_m"],
            sep["breach_rho0_m"],
            sep["breach_s"],
            sep["breach_pair"],
        )
    return {
        "rho0_m": rho0_m,
        "rho0_breach_m": depth,
        "time_below_rho0_s": below_s,
        "rho0_breach_by": by,
    }


def _separation(
    truths: dict[str, np.ndarray], radius: dict[str, float], rho0: dict[str, float]
) -> dict[str, Any]:
    """Smallest hull-to-hull distance between any two vehicles (and where: `closest`), how
    often two came into contact, and the pair that came deepest inside the larger of their
    two rho0 (how deep, that rho0, for how long); truths[id]: (n, 3) rows (t, x, y); the
    other's track is interpolated to each stamp of one's, over the time both were
    published."""
    best, pair, collisions = math.inf, "", 0
    closest: Approach | None = None
    breach: dict[str, Any] = {
        "breach_m": 0.0,
        "breach_rho0_m": 0.0,
        "breach_s": 0.0,
        "breach_pair": "",
    }
    for a, b in itertools.combinations(sorted(truths), 2):
        ta, tb = truths[a], truths[b]
        if len(ta) < 2 or len(tb) < 2:
            continue
        both = (ta[:, 0] >= tb[0, 0]) & (ta[:, 0] <= tb[-1, 0])
        t = ta[both, 0]
        if not len(t):
            continue
        bx, by = np.interp(t, tb[:, 0], tb[:, 1]), np.interp(t, tb[:, 0], tb[:, 2])
        gap = np.hypot(ta[both, 1] - bx, ta[both, 2] - by) - (radius[a] + radius[b])
        touching = gap < 0.0
        collisions += int(np.count_nonzero(touching[1:] & ~touching[:-1]) + int(touching[0]))
        i = int(gap.argmin())
        least = float(gap[i])
        if least < best:
            best, pair = least, f"{a}-{b}"
            a_xy = (float(ta[both, 1][i]), float(ta[both, 2][i]))
            closest = Approach(a, b, float(t[i]), least, a_xy, (float(bx[i]), float(by[i])))
        keep = max(rho0[a], rho0[b])
        if keep - least > breach["breach_m"]:
            breach.update(
                breach_m=keep - least,
                breach_rho0_m=keep,
                breach_s=duration_s(t, gap < keep),
                breach_pair=f"{a}-{b}",
            )
    return {
        "min_separation_m": best,
        "pair": pair,
        "closest": closest,
        "collisions": collisions,
        **breach,
    }
