"""The mission registry: the names `[run] mission` may take, a plain mapping to import targets.

A scenario names a mission; it never names code. MISSIONS maps each built-in name to an
import target ("module:Class"); the environment variable TIDELINK_MISSIONS adds more, as
comma-separated `name=module:Class` entries, e.g.

    TIDELINK_MISSIONS=testloop=tests.helpers.testloop:TestLoop

An environment variable reaches every process a run starts (services, routers, launched
hosts) and needs no packaging metadata, so it works alike from a checkout and a built wheel;
the tests register their self-test loop this way (tests/conftest.py).

Looking a name up imports nothing: only `common.runtime.model.mission.load_mission` imports
a target, and only a registered one. The older spelling of a value, the target itself
("services.mission:AuvMission"), is accepted when it is exactly a registered target.
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from types import MappingProxyType

from common.config.errors import ConfigError

MISSIONS: Mapping[str, str] = MappingProxyType({"auv": "services.mission:AuvMission"})
MISSIONS_ENV = "TIDELINK_MISSIONS"


def registered_missions() -> dict[str, str]:
    """Every registered mission: name -> import target "module:Class", sorted by name."""
    added = parse_missions(os.environ.get(MISSIONS_ENV, ""))
    return dict(sorted({**added, **MISSIONS}.items()))


def parse_missions(text: str) -> dict[str, str]:
    """The missions a TIDELINK_MISSIONS value adds: "a=m:C, b=n:D" -> {"a": "m:C", "b": "n:D"}."""
    found: dict[str, str] = {}
    for entry in filter(None, (e.strip() for e in text.split(","))):
        name, _, target = (part.strip() for part in entry.partition("="))
        module, _, attr = target.partition(":")
        if not (name and module and attr) or name in MISSIONS:
            raise ConfigError(
                "",
                MISSIONS_ENV,
                f"{entry!r} is no mission entry, expected name=module:Class with a name other "
                f"than the built-in {', '.join(MISSIONS)}",
            )
        found[name] = target
    return found


def add_mission(value: str, name: str, target: str) -> str:
    """The TIDELINK_MISSIONS value that adds `name=target` to what `value` adds."""
    added = parse_missions(value) | {name: target}
    return ",".join(f"{n}={t}" for n, t in added.items())


def resolve_mission(text: str) -> tuple[str, str] | None:
    """(name, target) of the registered mission `text` names (by name, or by its exact
    registered target), or None if it names none."""
    registry = registered_missions()
    if text in registry:
        return text, registry[text]
    for name, target in registry.items():
        if target == text:
            return name, target
    return None


def unknown_mission(text: str) -> str:
    """The problem with a value that names no registered mission, listing the registered."""
    listed = ", ".join(f"{n!r} ({t})" for n, t in registered_missions().items())
    return (
        f"{text!r} is not a registered mission, expected one of {listed}; a mission is "
        f"built in (common/config/missions.py) or added by the environment variable "
        f"{MISSIONS_ENV}=name=module:Class, never imported from a path in the scenario"
    )
