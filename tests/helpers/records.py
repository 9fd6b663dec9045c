"""Typed run records for tests: a mission's metrics with the run's facts, most of them dull."""

from __future__ import annotations

from typing import Any

import msgspec

from common.runtime.metrics_record import METRICS_SCHEMA, SCHEMA_KEY, RunFacts, RunMetrics
from services.mission.records import AuvMetrics, FleetMetrics, Outcome


def facts(**given: Any) -> RunFacts:
    """A run's facts: an inproc run that ended at its goal, unless `given` says otherwise."""
    plain: dict[str, Any] = {
        "end_reason": "goal",
        "failure": "",
        "t_end_s": 0.0,
        "ticks": 0,
        "runtime": "inproc",
        "seed": 1,
        "link_stats": {},
        "bytes_per_message": {},
        "unresponsive_s": {},
        "record_rejected": {},
        "inputs_rejected": 0,
        "inputs_rejected_by_reason": {},
        "inputs_dropped": 0,
        "inputs_dropped_by_link": {},
        "filter_resets": 0,
        "filter_resets_by_service": {},
    }
    return RunFacts(**(plain | given))


def ran(mission: msgspec.Struct, **given: Any) -> RunMetrics[Any]:
    """`mission`'s metrics with the facts of a run (see `facts`)."""
    return RunMetrics(mission=mission, facts=facts(**given))


def auv(outcome: Outcome, **fields: Any) -> AuvMetrics:
    """One vehicle's metrics with this outcome (and success when it is one), and `fields`."""
    plain = {
        "trajectory_sha256": "",
        "controller": "nurbs",
        "reached_goal": outcome in ("success", "rho0_breach"),
        "success": outcome == "success",
    }
    return AuvMetrics(outcome=outcome, **(plain | fields))


# the keys a metrics.json object of each mission always has, at dull values
AUV_KEYS: dict[str, Any] = {
    "trajectory_sha256": "",
    "controller": "nurbs",
    "reached_goal": False,
    "outcome": "not_reached",
    "success": False,
}
FLEET_KEYS: dict[str, Any] = AUV_KEYS | {
    "fleet_size": 2,
    "vehicles_reached": 0,
    "makespan_s": None,
    "travel_time_s": 0.0,
    "min_separation_m": None,
    "min_separation_pair": "",
    "min_separation_t_s": None,
    "vehicle_collisions": 0,
    "collisions": 0,
    "min_clearance_m": None,
    "rho0_m": None,
    "rho0_breach_m": 0.0,
    "time_below_rho0_s": 0.0,
    "rho0_breach_by": "",
    "hold_time_s": 0.0,
    "failsafe_time_s": 0.0,
    "intent_fraction": None,
    "vehicles": {},
}


def from_json(flat: dict[str, Any], mission: type[Any] = AuvMetrics) -> RunMetrics[Any]:
    """The record of a metrics.json object holding `flat` (the other keys it must have at
    dull values; a fleet's vehicles' too)."""
    keys = FLEET_KEYS if mission is FleetMetrics else AUV_KEYS if mission is AuvMetrics else {}
    data = msgspec.to_builtins(facts()) | keys | flat | {SCHEMA_KEY: METRICS_SCHEMA}
    if mission is FleetMetrics:
        data["vehicles"] = {vid: AUV_KEYS | v for vid, v in data["vehicles"].items()}
    return RunMetrics.decode(data, mission)
