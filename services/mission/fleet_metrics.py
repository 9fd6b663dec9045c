"""Metrics of a fleet run: each vehicle's, under its id, and the fleet's (all reached, makespan,
separation between any two hulls, vehicle-vehicle collisions, deconfliction by intent or by
track)."""

from __future__ import annotations

import hashlib
import itertools
import math
from typing import NamedTuple, TypedDict

import msgspec
import numpy as np

from common.config.scenario import Scenario
from common.messages import TruthState
from common.runtime.model.dataflow import qualified
from common.runtime.model.record import Record
from common.world import World
from services.mission.metrics import duration_s, last_counters, mission_metrics
from services.mission.outcome import classify
from services.mission.records import AuvMetrics, FleetMetrics, given


def fleet_metrics(record: Record, s: Scenario) -> FleetMetrics:
    """The fleet's metrics; `vehicles` holds each vehicle's (services/mission/metrics.py)."""
    per = {vid: mission_metrics(record, m, World(m.world), vehicle=vid) for vid, m in s.members}
    tallies = {vid: _intent_tallies(record, vid) for vid in per}
    for vid, (by_intent, by_track) in tallies.items():
        per[vid] = msgspec.structs.replace(per[vid], **_intent_metrics(by_intent, by_track))
    rho0 = _rho0s(s)
    sep = _separation(fleet_truths(record, s), _radii(s), rho0)
    reached = all(m.reached_goal for m in per.values())
    arrivals = [given(m.travel_time_s, 0.0) for m in per.values() if m.reached_goal]
    collisions = sum(given(m.collisions, 0) for m in per.values())
    breach = _deepest_breach(per, sep, min(rho0.values()))
    outcome = classify(
        reached_goal=reached,
        contact=collisions > 0 or sep.collisions > 0,
        below_rho0=breach.depth_m > 0.0,
    )
    return FleetMetrics(
        trajectory_sha256=hashlib.sha256(
            "".join(per[v].trajectory_sha256 for v in sorted(per)).encode()
        ).hexdigest(),
        controller=",".join(sorted({m.controller for m in per.values()})),
        fleet_size=len(per),
        reached_goal=reached,
        vehicles_reached=len(arrivals),
        makespan_s=max(arrivals) if reached and arrivals else None,
        # what a run's outcome is told in (services/mission/outcome.py): the last arrival
        travel_time_s=max(arrivals, default=0.0),
        min_separation_m=sep.min_separation_m,
        min_separation_pair=sep.pair,
        min_separation_t_s=sep.closest.t_s if sep.closest is not None else None,
        vehicle_collisions=sep.collisions,
        collisions=collisions,
        min_clearance_m=min(
            (v for m in per.values() if isinstance(v := m.min_clearance_m, float)),
            default=math.nan,
        ),
        rho0_m=breach.rho0_m,
        rho0_breach_m=breach.depth_m,
        time_below_rho0_s=breach.below_s,
        rho0_breach_by=breach.by,
        hold_time_s=sum(given(m.hold_time_s, 0.0) for m in per.values()),
        failsafe_time_s=sum(given(m.failsafe_time_s, 0.0) for m in per.values()),
        # of every planner step x other vehicle, the share handled by a fresh intent
        intent_fraction=_share(
            sum(sum(i.values()) for i, _ in tallies.values()),
            sum(sum(k.values()) for _, k in tallies.values()),
        ),
        outcome=outcome,
        success=outcome == "success",
        vehicles=per,
    )


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
    return _separation(fleet_truths(record, s), _radii(s), _rho0s(s)).closest


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


class Intents(TypedDict):
    """A fleet vehicle's AuvMetrics fields of the others' intents."""

    intent_fraction: float | None
    intent_fraction_by_vehicle: dict[str, float | None]


def _intent_metrics(by_intent: dict[str, int], by_track: dict[str, int]) -> Intents:
    """intent_fraction (all others together) and, per other vehicle,
    intent_fraction_by_vehicle."""
    others = sorted(set(by_intent) | set(by_track))
    return Intents(
        intent_fraction=_share(sum(by_intent.values()), sum(by_track.values())),
        intent_fraction_by_vehicle={
            o: _share(by_intent.get(o, 0), by_track.get(o, 0)) for o in others
        },
    )


class Breach(NamedTuple):
    """The deepest way inside a safety distance: how deep (m), of which rho0 (m), for how
    long (s), by whom (a vehicle, a pair "a-b", or "")."""

    depth_m: float
    rho0_m: float
    below_s: float
    by: str


def _deepest_breach(per: dict[str, AuvMetrics], sep: Separation, least_rho0: float) -> Breach:
    """The deepest way inside a safety distance anyone came, in its own terms: a vehicle
    inside its own rho0 of an obstacle, or two hulls inside the larger of their two rho0
    (each vehicle keeps its own from everything around it); rho0_breach_by names the vehicle
    or the pair ("" without a breach, rho0_m then the least rho0: what every vehicle kept)."""
    deepest = Breach(0.0, least_rho0, 0.0, "")
    for vid, m in sorted(per.items()):
        if given(m.rho0_breach_m, 0.0) > deepest.depth_m:
            deepest = Breach(
                float(given(m.rho0_breach_m, 0.0)),
                float(given(m.rho0_m, math.nan)),
                float(given(m.time_below_rho0_s, 0.0)),
                vid,
            )
    if sep.breach.depth_m > deepest.depth_m:
        return sep.breach
    return deepest


class Separation(NamedTuple):
    """How close the fleet's hulls came: the least gap (m, inf: fewer than two tracks), its
    pair and where, contacts between hulls, and the pair deepest inside its rho0."""

    min_separation_m: float
    pair: str
    closest: Approach | None
    collisions: int
    breach: Breach


def _separation(
    truths: dict[str, np.ndarray], radius: dict[str, float], rho0: dict[str, float]
) -> Separation:
    """Smallest hull-to-hull distance between any two vehicles (and where: `closest`), how
    often two came into contact, and the pair that came deepest inside the larger of their
    two rho0 (how deep, that rho0, for how long); truths[id]: (n, 3) rows (t, x, y); the
    other's track is interpolated to each stamp of one's, over the time both were
    published."""
    best, pair, collisions = math.inf, "", 0
    closest: Approach | None = None
    breach = Breach(0.0, 0.0, 0.0, "")
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
        if keep - least > breach.depth_m:
            breach = Breach(keep - least, keep, duration_s(t, gap < keep), f"{a}-{b}")
    return Separation(best, pair, closest, collisions, breach)
