"""The mission registry: the names `[run] mission` may take (entry points tidelink.missions).

A scenario names a mission; it never names code. The registry maps each name to an import
target ("module:Class") declared by an installed distribution in its entry points, e.g. in
pyproject.toml:

    [project.entry-points."tidelink.missions"]
    auv = "services.mission:AuvMission"

Looking a name up imports nothing: only `common.runtime.model.mission.load_mission` imports
a target, and only a registered one. The older spelling of a value, the target itself
("services.mission:AuvMission"), is accepted when it is exactly a registered target.

Where tidelink runs from a source checkout (an editable install, or PYTHONPATH=.), the
checkout's own pyproject.toml table is read instead of the installed metadata of tidelink:
an editable install's entry points are only as new as its last `pip install -e`, the
checkout's table is the one that matches the code that runs.
"""

from __future__ import annotations

import tomllib
from functools import lru_cache
from importlib.metadata import entry_points
from pathlib import Path

GROUP = "tidelink.missions"
DISTRIBUTION = "tidelink"
# the checkout this module belongs to: <root>/common/config/missions.py -> <root>/pyproject.toml
_CHECKOUT_PYPROJECT = Path(__file__).resolve().parents[2] / "pyproject.toml"


@lru_cache(maxsize=1)
def registered_missions() -> dict[str, str]:
    """Every registered mission: name -> import target "module:Class", sorted by name.

    Cached for the life of the process: entry points do not change while it runs.
    """
    checkout = _checkout_missions(_CHECKOUT_PYPROJECT)
    found: dict[str, str] = {}
    for ep in entry_points(group=GROUP):
        dist = getattr(ep, "dist", None)
        if checkout is not None and dist is not None and dist.name == DISTRIBUTION:
            continue  # this checkout's table below is newer than its installed metadata
        found[ep.name] = ep.value
    found.update(checkout or {})
    return dict(sorted(found.items()))


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
    listed = ", ".join(f"{n!r} ({t})" for n, t in registered_missions().items()) or "none"
    return (
        f"{text!r} is not a registered mission, expected one of {listed}; a mission is "
        f'registered as an entry point in group "{GROUP}" (pyproject.toml), never imported '
        "from a path in the scenario"
    )


def _checkout_missions(pyproject: Path) -> dict[str, str] | None:
    """The mission table of tidelink's pyproject.toml at `pyproject`, or None if there is none
    (an installed, non-editable tidelink: its metadata is then the only source)."""
    try:
        data = tomllib.loads(pyproject.read_text())
    except (OSError, tomllib.TOMLDecodeError):
        return None
    project = data.get("project", {})
    if project.get("name") != DISTRIBUTION:
        return None
    table = project.get("entry-points", {}).get(GROUP, {})
    return {str(k): str(v) for k, v in table.items()}
