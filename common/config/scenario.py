"""The scenario: every section of a TOML scenario file as one frozen dataclass.

Loading checks every value on its own. Checks that need more than the config (the world's
geometry: common.world.check) are passed in as `check`, so this package imports nothing above
it.
"""

from __future__ import annotations

import copy
import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.config.bus import BusConfig
from common.config.controller import ControllerConfig
from common.config.errors import ConfigValueError, KeyPath
from common.config.estimator import EstimatorConfig
from common.config.fleet import FleetVehicle, fleet_from_raw
from common.config.loader import (
    ConfigError,
    apply_override,
    build,
    parse_override,
    read_scenario_toml,
)
from common.config.network import NetworkConfig
from common.config.placement import PlacementConfig
from common.config.planner import PlannerConfig
from common.config.run import RunConfig, RuntimeConfig
from common.config.sensor import SensorConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from common.jsonsafe import JsonObject
from common.messages import SEQUENCE_STEP_MAX_MS, SEQUENCE_STEP_MIN_MS

# A check run after a scenario is built: (scenario, file) -> None, raising ConfigError.
ScenarioCheck = Callable[["Scenario", str], None]


@dataclass(frozen=True, kw_only=True)
class Scenario:
    """A whole scenario; sections default to their dataclass defaults when absent."""

    run: RunConfig = field(default_factory=RunConfig)
    runtime: RuntimeConfig = field(default_factory=RuntimeConfig)
    bus: BusConfig = field(default_factory=BusConfig)
    network: NetworkConfig = field(default_factory=NetworkConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    vehicle: VehicleConfig = field(default_factory=VehicleConfig)
    sensor: SensorConfig = field(default_factory=SensorConfig)
    estimator: EstimatorConfig = field(default_factory=EstimatorConfig)
    planner: PlannerConfig = field(default_factory=PlannerConfig)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    placement: PlacementConfig = field(default_factory=PlacementConfig)
    # a fleet ([[vehicles]], common/config/fleet.py); () is one vehicle, world.start to goal
    vehicles: tuple[FleetVehicle, ...] = ()

    def __post_init__(self) -> None:
        _check_sequence(self.controller, self.planner.period_s, self.vehicle)

    def member(self, v: FleetVehicle) -> Scenario:
        """The scenario of one vehicle of the fleet: its start, goal and sections, the
        scenario's everything else, and no fleet."""
        return dataclasses.replace(
            self,
            world=dataclasses.replace(self.world, start=v.start, goal=v.goal),
            vehicle=v.vehicle,
            sensor=v.sensor,
            estimator=v.estimator,
            planner=v.planner,
            controller=v.controller,
            vehicles=(),
        )

    @property
    def members(self) -> tuple[tuple[str, Scenario], ...]:
        """(vehicle id, its scenario) of every vehicle of the fleet; () for one vehicle."""
        return tuple((v.id, self.member(v)) for v in self.vehicles)


def _check_sequence(ctrl: ControllerConfig, period_s: float, vehicle: VehicleConfig) -> None:
    """A command sequence the vehicle would refuse (too many entries, too long a horizon, a
    step that is no whole number of milliseconds) is a config error, not a mission spent in
    HOLD with every command rejected; so is a horizon too short for its stop tail."""
    n = ctrl.sequence.entries(period_s)
    if n == 0:
        return
    wd = vehicle.watchdog
    key = ("controller", "sequence", "horizon_s")
    step_ms = period_s * 1000
    if abs(step_ms - round(step_ms)) > 1e-6 or not (
        SEQUENCE_STEP_MIN_MS <= round(step_ms) <= SEQUENCE_STEP_MAX_MS
    ):
        raise ConfigValueError(
            ("planner", "period_s"),
            f"{period_s!r} is no whole number of milliseconds in [{SEQUENCE_STEP_MIN_MS}, "
            f"{SEQUENCE_STEP_MAX_MS}] ms, as the step of a command sequence must be (or set "
            "controller.sequence.horizon_s = 0)",
        )
    if n > wd.max_sequence_len:
        raise ConfigValueError(
            key,
            f"{ctrl.sequence.horizon_s!r} s is {n} entries at planner.period_s {period_s!r}, "
            f"more than the vehicle accepts (vehicle.watchdog.max_sequence_len = "
            f"{wd.max_sequence_len})",
        )
    stop_s = vehicle.cruise_speed_mps / vehicle.accel_max_mps2
    if ctrl.sequence.stop_tail and n * period_s < stop_s - 1e-9:
        raise ConfigValueError(
            key,
            f"{ctrl.sequence.horizon_s!r} s is shorter than the stop tail needs to brake from "
            f"cruise ({vehicle.cruise_speed_mps!r} m/s at vehicle.accel_max_mps2 "
            f"{vehicle.accel_max_mps2!r}: {stop_s:.3g} s): the vehicle would never run at "
            "cruise; lengthen it or set controller.sequence.stop_tail = false",
        )
    if n * period_s > wd.max_horizon_s + 1e-9:
        raise ConfigValueError(
            key,
            f"{ctrl.sequence.horizon_s!r} s reaches further than the vehicle accepts "
            f"(vehicle.watchdog.max_horizon_s = {wd.max_horizon_s!r})",
        )


def load_scenario(
    path: str | Path,
    overrides: list[str] | None = None,
    seed: int | None = None,
    *,
    check: ScenarioCheck | None = None,
) -> tuple[Scenario, JsonObject]:
    """Read, override (`--set key=value`) and validate a scenario; returns it and its raw data.

    The raw mapping is returned so it can be handed to child processes unchanged. Whoever
    loads a scenario to run it passes `check=common.world.check.check_scenario`.
    """
    raw = read_scenario_toml(path)
    in_file = copy.deepcopy(raw)
    given: list[tuple[KeyPath, str]] = []  # (key, the flag that set it), to blame errors on
    for text in overrides or []:
        parts, value = parse_override(text)
        apply_override(raw, parts, value)
        given.append((tuple(parts), "--set"))
    if seed is not None:
        apply_override(raw, ["run", "seed"], seed)
        given.append((("run", "seed"), "--seed"))
    try:
        return scenario_from_raw(raw, str(path), check=check), raw
    except ConfigError as exc:
        flag = _flag_of(exc.key_path, given, in_file)
        if flag is None:
            raise
        raise ConfigError(flag, exc.key_path, exc.problem) from None


def _flag_of(key: KeyPath, given: list[tuple[KeyPath, str]], in_file: JsonObject) -> str | None:
    """The flag (--set, --seed) an error at `key` comes from, or None (the file's): the last
    one that set this key or a table above it, or that named this key when the file has no
    such key (an unknown table or key only the flag made up). An error at a key of the file
    that a flag set something below (world.start, after --set world.start.x_m) stays the
    file's: it names what the file and the flag made together."""
    at = tuple(str(k) for k in key)
    for parts, flag in reversed(given):
        if at[: len(parts)] == parts and len(at) >= len(parts):
            return flag
        if at and parts[: len(at)] == at and not _has(in_file, at):
            return flag
    return None


def _has(tables: JsonObject, key: tuple[str, ...]) -> bool:
    """Whether the file's own tables hold `key` (tables only: an array's elements are not
    followed)."""
    node: Any = tables
    for part in key:
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def scenario_from_raw(
    raw: JsonObject, file: str = "", *, check: ScenarioCheck | None = None
) -> Scenario:
    """Validate a raw mapping (from TOML or a parent process) into a Scenario, then `check` it."""
    try:
        # [[vehicles]] override the scenario's sections key by key: merged, then built
        scenario = build(Scenario, {k: v for k, v in raw.items() if k != "vehicles"}, file=file)
        fleet = fleet_from_raw(raw, file)
    except ConfigError:
        raise
    except TypeError as exc:  # a programming error in a config dataclass, still say where
        raise ConfigError(file, (), str(exc)) from None
    if fleet:
        scenario = dataclasses.replace(scenario, vehicles=fleet)
        for i, v in enumerate(fleet):
            try:
                scenario.member(v)
            except ConfigValueError as exc:  # a member's sections that do not fit together
                raise ConfigError(file, ("vehicles", i, *exc.key_path), exc.problem) from None
    if check is not None:
        check(scenario, file)
    return scenario
