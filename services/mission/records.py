"""The AUV mission's metrics as typed records: one vehicle's (AuvMetrics) and a fleet's
(FleetMetrics), the mission half of metrics.json (common/runtime/metrics_record.py).

Field names are metrics.json's keys (docs/metrics.md, docs/fleets.md). A key the run could not
measure is UNSET (absent from the file: no truth, no planned path, no estimate, no moving
obstacle, ...); None is a measurement that came out as nothing (no obstacle in the world, a
non-finite value). `given` reads either as a default.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, TypeVar

import msgspec
from msgspec import UNSET, UnsetType

from common.runtime.metrics_record import RunMetrics, read_object

T = TypeVar("T")
D = TypeVar("D")
S = TypeVar("S", bound=msgspec.Struct)

# how a run ended, strongest first (services/mission/outcome.py says by which rule)
Outcome = Literal["success", "rho0_breach", "collision", "not_reached"]
OUTCOMES: tuple[Outcome, ...] = ("success", "rho0_breach", "collision", "not_reached")

# a measurement; None (null in the file) when it came out as nothing: no obstacle in the
# world, a non-finite value (JSON has none)
Num = float | None
Opt = UnsetType  # spelled `X | Opt = UNSET`: absent when not measured


class AuvMetrics(msgspec.Struct, kw_only=True, frozen=True):
    """One vehicle's metrics (services/mission/metrics.py computes them)."""

    trajectory_sha256: str
    controller: str
    reached_goal: bool
    outcome: Outcome
    success: bool  # outcome == "success"
    # the true track (absent without a truth state)
    travel_time_s: Num | Opt = UNSET  # eq. (21)
    mean_speed_mps: Num | Opt = UNSET
    path_length_m: Num | Opt = UNSET
    f_l_executed: Num | Opt = UNSET  # None: start and goal coincide
    final_distance_to_goal_m: Num | Opt = UNSET
    # clearance of the hull to the obstacles (eq. 12); None: no obstacle in the world
    min_clearance_m: Num | Opt = UNSET
    min_clearance_t_s: Num | Opt = UNSET
    collisions: int | Opt = UNSET
    first_contact_t_s: Num | Opt = UNSET  # only after a contact
    time_in_contact_s: Num | Opt = UNSET
    rho0_m: Num | Opt = UNSET
    rho0_breach_m: Num | Opt = UNSET
    time_below_rho0_s: Num | Opt = UNSET
    # turns
    max_executed_curvature: Num | Opt = UNSET
    max_executed_curvature_after_start: Num | Opt = UNSET
    time_above_curvature_limit_s: Num | Opt = UNSET
    max_ground_curvature: Num | Opt = UNSET
    # plans and commands
    replans: int | Opt = UNSET
    no_path_events: int | Opt = UNSET
    plans_declined: int | Opt = UNSET
    plans_declined_by_reason: dict[str, int] | Opt = UNSET
    replans_by_reason: dict[str, int] | Opt = UNSET
    # the paths published by the strategy that made them, and the strategies rejected on the
    # way to them (services/planner/reasons.py); absent in a record of paths without codes
    plan_strategies: dict[str, int] | Opt = UNSET
    plan_strategies_rejected: dict[str, int] | Opt = UNSET
    control_actions: int | Opt = UNSET
    # against the first planned path (absent without one)
    planned_length_m: Num | Opt = UNSET
    planned_f_l: Num | Opt = UNSET
    planned_max_curvature: Num | Opt = UNSET
    xte_optimal_rms_m: Num | Opt = UNSET
    xte_optimal_max_m: Num | Opt = UNSET
    path_reentries: int | Opt = UNSET
    xte_planned_rms_m: Num | Opt = UNSET
    xte_planned_max_m: Num | Opt = UNSET
    control_actions_on_path: int | Opt = UNSET
    # the estimator against truth (absent without an estimate)
    estimation_rms_m: Num | Opt = UNSET
    estimation_max_m: Num | Opt = UNSET
    heading_error_rms_rad: Num | Opt = UNSET
    current_error_rms_mps: Num | Opt = UNSET
    nees_mean: Num | Opt = UNSET  # None: no covariance said anything
    nees_in_band: Num | Opt = UNSET
    # tracks of the world's moving obstacles (absent without one; None: none measured)
    tracking_rms_m: Num | Opt = UNSET
    tracking_max_m: Num | Opt = UNSET
    tracking_ahead_rms_m: Num | Opt = UNSET
    tracking_ahead_max_m: Num | Opt = UNSET
    # the vehicle's watchdog (absent without a status)
    commands_applied: int | Opt = UNSET
    commands_rejected: int | Opt = UNSET
    commands_rejected_stale: int | Opt = UNSET
    commands_rejected_by_reason: dict[str, int] | Opt = UNSET
    commands_clamped: int | Opt = UNSET
    hold_time_s: Num | Opt = UNSET
    failsafe_time_s: Num | Opt = UNSET
    hold_distance_max_m: Num | Opt = UNSET
    # a fleet vehicle's steps by the others' intents (services/mission/fleet_metrics.py)
    intent_fraction: Num | Opt = UNSET
    intent_fraction_by_vehicle: dict[str, float | None] | Opt = UNSET


class FleetMetrics(msgspec.Struct, kw_only=True, frozen=True):
    """A fleet's metrics, each vehicle's under its id (services/mission/fleet_metrics.py)."""

    trajectory_sha256: str  # of the vehicles' own, in id order
    controller: str  # the controllers that ran, comma-separated
    fleet_size: int
    reached_goal: bool  # every vehicle did
    vehicles_reached: int
    makespan_s: Num  # the last arrival; None unless all arrived
    travel_time_s: Num  # the last arrival so far
    min_separation_m: Num  # hull to hull; None: fewer than two tracks
    min_separation_pair: str
    min_separation_t_s: Num
    vehicle_collisions: int
    collisions: int  # with obstacles, all vehicles'
    min_clearance_m: Num
    rho0_m: Num
    rho0_breach_m: Num
    time_below_rho0_s: Num
    rho0_breach_by: str  # the vehicle, or the pair "a-b"; "" without a breach
    hold_time_s: Num
    failsafe_time_s: Num
    intent_fraction: Num
    outcome: Outcome
    success: bool
    vehicles: dict[str, AuvMetrics]


MissionMetrics = AuvMetrics | FleetMetrics
# a run of the AUV mission, as `tidelink run`, `launch` and a sweep return it
AuvRun = RunMetrics[AuvMetrics] | RunMetrics[FleetMetrics]


def given(v: T | UnsetType | None, default: D) -> T | D:
    """A metric's value, `default` when it is absent (UNSET) or null (None)."""
    return default if v is None or isinstance(v, UnsetType) else v


def build(cls: type[S], fields: Mapping[str, object]) -> S:
    """A `cls` record of `fields` by name, each value checked against its field's type; a name
    that is no field of `cls` is an error (msgspec.convert alone would drop it unseen)."""
    unknown = sorted(set(fields) - set(cls.__struct_fields__))
    if unknown:
        raise TypeError(f"{cls.__name__} has no field {', '.join(unknown)}")
    return msgspec.convert(fields, cls)


def auv_metrics(m: RunMetrics[Any]) -> MissionMetrics | None:
    """The AUV mission's metrics of a run; None for another mission's (the runtime's test
    loop), which this mission does not judge."""
    mission = m.mission
    return mission if isinstance(mission, AuvMetrics | FleetMetrics) else None


def read_metrics(path: Path) -> AuvRun:
    """A run's metrics.json of the AUV mission, one vehicle's or a fleet's (OSError,
    ValueError: cannot be read; MetricsSchemaError: of another version of tidelink)."""
    data = read_object(path)
    if "fleet_size" in data:
        return RunMetrics.decode(data, FleetMetrics, str(path))
    return RunMetrics.decode(data, AuvMetrics, str(path))
