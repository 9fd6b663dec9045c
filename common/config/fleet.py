"""A fleet's `[[vehicles]]`: each AUV's id, start and goal, and its own overrides of the sections.

An entry's `vehicle`, `sensor`, `estimator`, `planner` and `controller` tables override the
scenario's tables key by key (what an entry leaves out stays the scenario's), so a fleet of
identical vehicles needs only ids, starts and goals. Every merged section is checked where the
entry wrote it: an error names `vehicles[i].planner.rho0_m`, not `planner.rho0_m`.

`phase_s` shifts every periodic service of the vehicle that much later in its period (its own
computer's clock phase): vehicles in phase step at the same instants, and in realtime their
steps queue for the same cores at once.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, TypeGuard

from common.config.controller import ControllerConfig
from common.config.errors import ConfigError
from common.config.estimator import EstimatorConfig
from common.config.loader import build, merge_tables
from common.config.network import OTHER
from common.config.planner import PlannerConfig
from common.config.sensor import SensorConfig
from common.config.vehicle import VehicleConfig
from common.config.world import GoalConfig, PoseConfig
from common.jsonsafe import JsonObject, JsonValue

MAX_VEHICLES = 16
# a vehicle id qualifies its services' names ("auv2.planner") and is a key chunk: no '.'
_ID = re.compile(r"^[A-Za-z0-9_\-]+$")
# the sections an entry may override, and the config each builds into
SECTIONS: dict[str, type] = {
    "vehicle": VehicleConfig,
    "sensor": SensorConfig,
    "estimator": EstimatorConfig,
    "planner": PlannerConfig,
    "controller": ControllerConfig,
}
ENTRY_KEYS = ("id", "start", "goal", "phase_s", *SECTIONS)


@dataclass(frozen=True, kw_only=True)
class FleetVehicle:
    """One AUV of a fleet: its id, start and goal, and its sections after its overrides."""

    id: str
    start: PoseConfig
    goal: GoalConfig
    vehicle: VehicleConfig
    sensor: SensorConfig
    estimator: EstimatorConfig
    planner: PlannerConfig
    controller: ControllerConfig
    phase_s: float = 0.0  # its services step this much later in their periods


def _is_tables(v: JsonValue) -> TypeGuard[list[JsonObject]]:
    """An array of tables (`[[vehicles]]`)."""
    return isinstance(v, list) and all(isinstance(e, dict) for e in v)


def fleet_from_raw(raw: JsonObject, file: str = "") -> tuple[FleetVehicle, ...]:
    """The `[[vehicles]]` of a raw scenario mapping, each section merged over the scenario's;
    () when there are none. ConfigError names the entry and key of the first problem."""
    entries = raw.get("vehicles", [])
    if not _is_tables(entries):
        raise ConfigError(file, ("vehicles",), "expected an array of tables ([[vehicles]])")
    if len(entries) > MAX_VEHICLES:
        raise ConfigError(
            file, ("vehicles",), f"{len(entries)} vehicles, at most {MAX_VEHICLES} are supported"
        )
    seen: set[str] = set()
    out = []
    for i, e in enumerate(entries):
        at = ("vehicles", i)
        unknown = sorted(set(e) - set(ENTRY_KEYS))
        if unknown:
            raise ConfigError(
                file, (*at, unknown[0]), f"unknown key (known keys: {', '.join(ENTRY_KEYS)})"
            )
        for key in ("id", "start", "goal"):
            if key not in e:
                raise ConfigError(file, (*at, key), "required key is missing")
        vid = e["id"]
        if not isinstance(vid, str) or not _ID.match(vid):
            raise ConfigError(file, (*at, "id"), f"{vid!r} must be letters, digits, '_' or '-'")
        if vid == OTHER:
            raise ConfigError(
                file, (*at, "id"), f"{vid!r} is reserved (network links name another vehicle so)"
            )
        if vid in seen:
            raise ConfigError(file, (*at, "id"), f"{vid!r} is used twice, expected unique ids")
        seen.add(vid)
        phase = e.get("phase_s", 0.0)
        if (
            isinstance(phase, bool)
            or not isinstance(phase, int | float)
            or not (math.isfinite(phase) and phase >= 0.0)
        ):
            raise ConfigError(file, (*at, "phase_s"), f"{phase!r} must be a finite number >= 0")
        sections: dict[str, Any] = {
            name: build(
                cls, merge_tables(raw.get(name, {}), e.get(name, {})), file=file, path=(*at, name)
            )
            for name, cls in SECTIONS.items()
        }
        out.append(
            FleetVehicle(
                id=vid,
                start=build(PoseConfig, e["start"], file=file, path=(*at, "start")),
                goal=build(GoalConfig, e["goal"], file=file, path=(*at, "goal")),
                phase_s=float(phase),
                **sections,
            )
        )
    return tuple(out)
