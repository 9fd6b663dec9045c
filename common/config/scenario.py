"""The scenario: every section of a TOML scenario file as one frozen dataclass.

Loading checks every value on its own. Checks that need more than the config (the world's
geometry: common.world.check) are passed in as `check`, so this package imports nothing above
it.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.config.bus import BusConfig
from common.config.controller import ControllerConfig
from common.config.estimator import EstimatorConfig
from common.config.loader import ConfigError, apply_override, build, parse_override, read_toml
from common.config.network import NetworkConfig
from common.config.planner import PlannerConfig
from common.config.run import RunConfig, RuntimeConfig
from common.config.sensor import SensorConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig

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


def load_scenario(
    path: str | Path,
    overrides: list[str] | None = None,
    seed: int | None = None,
    *,
    check: ScenarioCheck | None = None,
) -> tuple[Scenario, dict[str, Any]]:
    """Read, override (`--set key=value`) and validate a scenario; returns it and its raw data.

    The raw mapping is returned so it can be handed to child processes unchanged. Whoever
    loads a scenario to run it passes `check=common.world.check.check_scenario`.
    """
    raw = read_toml(path)
    for text in overrides or []:
        parts, value = parse_override(text)
        apply_override(raw, parts, value)
    if seed is not None:
        apply_override(raw, ["run", "seed"], seed)
    return scenario_from_raw(raw, str(path), check=check), raw


def scenario_from_raw(
    raw: dict[str, Any], file: str = "", *, check: ScenarioCheck | None = None
) -> Scenario:
    """Validate a raw mapping (from TOML or a parent process) into a Scenario, then `check` it."""
    try:
        scenario = build(Scenario, raw, file=file)
    except ConfigError:
        raise
    except TypeError as exc:  # a programming error in a config dataclass, still say where
        raise ConfigError(file, (), str(exc)) from None
    if check is not None:
        check(scenario, file)
    return scenario
