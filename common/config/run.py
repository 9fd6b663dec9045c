"""Run-level settings: identity, seed, duration, which mission, and runtime tuning."""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Literal

from common.config.errors import ConfigValueError
from common.config.missions import resolve_mission, unknown_mission

_ID = re.compile(r"^[A-Za-z0-9_\-]+$")


@dataclass(frozen=True, kw_only=True)
class RunConfig:
    """Identity and scope of one run."""

    name: str = "demo"  # the run id in every key: tidelink/<name>/<vehicle>/...
    vehicle: str = "auv1"
    seed: int = 1
    max_time_s: float = 300.0  # virtual seconds; the mission ends here if not before
    # a registered mission's name (common/config/missions.py; the cores of the dataflow, its
    # end and its metrics); its registered "module:Class" is accepted too, nothing else
    mission: str = "auv"
    # the mission's own parameters ([run.mission_params]), checked by the mission itself
    mission_params: dict[str, bool | int | float | str] = field(default_factory=dict)

    def __post_init__(self) -> None:
        for name in ("name", "vehicle"):
            if not _ID.match(getattr(self, name)):
                raise ConfigValueError(name, "must be letters, digits, '_' or '-'")
        if not 0 <= self.seed < 2**63:
            raise ConfigValueError("seed", "must be in [0, 2**63)")
        if self.max_time_s <= 0:
            raise ConfigValueError("max_time_s", "must be > 0")
        if resolve_mission(self.mission) is None:  # checked by name: nothing is imported
            raise ConfigValueError("mission", unknown_mission(self.mission))

    @property
    def mission_name(self) -> str:
        """The registered name of the mission, however `mission` spells it."""
        found = resolve_mission(self.mission)
        return found[0] if found else self.mission


@dataclass(frozen=True, kw_only=True)
class RuntimeConfig:
    """Which runtime and how it behaves."""

    kind: Literal["inproc", "lockstep", "realtime"] = "inproc"
    time_scale: float = 1.0  # realtime only: 5.0 runs five times faster than the wall clock
    stats_period_s: float = 1.0  # virtual seconds between LinkStats publications
    # for every service process to declare liveliness; in realtime also how long the launcher
    # waits for a service whose token vanished, and a service cut off from its router waits
    # to rejoin it
    start_timeout_s: float = 30.0
    tick_timeout_s: float = 30.0  # lockstep: a service that does not acknowledge a tick fails
    # realtime only: how long after its step (mission s) a core prepares its next one (the
    # planner's command sequence past its first entries, core.Prepares), out of the way of the
    # work the step's outputs set off at that instant (the vehicle applying the command; in a
    # fleet, every vehicle's services stepping at the same instants); never later than its
    # next step. 0: at once, once the outputs are out. Lockstep and inproc prepare at once.
    prepare_delay_s: float = 0.02

    def __post_init__(self) -> None:
        if not 0.01 <= self.time_scale <= 1000:
            raise ConfigValueError("time_scale", "must be in [0.01, 1000]")
        if not 0.0 <= self.prepare_delay_s <= 10.0:
            raise ConfigValueError("prepare_delay_s", "must be in [0, 10] s")
        for name in ("stats_period_s", "start_timeout_s", "tick_timeout_s"):
            if getattr(self, name) <= 0:
                raise ConfigValueError(name, "must be > 0")
