"""The Foxglove app's layout (docs/foxglove/tidelink-layout.json), made for a fleet: each panel
shows every vehicle.

The shipped layout reads one vehicle's topics (`/vehicle/pose_true`, `/plot/truth...`). A
fleet's view puts each vehicle's topics under its id (`/auv2/vehicle/pose_true`) and keeps
the run's own (the chart, the moving obstacles, events, links, the run's info and end) as
they are (services/foxglove/view.py). The fleet layout is the shipped one with each
vehicle-scoped topic repeated per vehicle: the 3D panel draws every vehicle (its truth in the
vehicle's colour, its estimate in the same, half transparent), each plot and state panel has a
series per vehicle, labelled with its id, in the vehicle's colour.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from services.foxglove.view import FLEET_RUN_TOPICS, vehicle_topic

SHIPPED = Path(__file__).resolve().parents[2] / "docs" / "foxglove" / "tidelink-layout.json"
SINGLE_FRAMES = ("auv", "auv_est")  # the single vehicle's frames on /tf, a fleet's are its ids
# a vehicle's colour in every panel (Material 800 tones, told apart on a white chart)
PALETTE = (
    "#1565c0",
    "#c62828",
    "#2e7d32",
    "#6a1b9a",
    "#ef6c00",
    "#00838f",
    "#4e342e",
    "#ad1457",
    "#283593",
    "#9e9d24",
    "#37474f",
    "#00695c",
    "#d84315",
    "#4527a0",
    "#558b2f",
    "#0277bd",
)


def shipped_layout(path: Path = SHIPPED) -> dict[str, Any]:
    """The single-vehicle layout, as shipped."""
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise ValueError(f"cannot read the Foxglove layout {path}: {exc}") from None
    if not isinstance(data, dict) or "configById" not in data:
        raise ValueError(f"{path} is not a Foxglove layout (no configById)")
    return data


def fleet_layout(single: dict[str, Any], vehicles: Sequence[str]) -> dict[str, Any]:
    """`single` with every vehicle-scoped topic repeated for each of `vehicles` (an empty
    sequence: a single vehicle, `single` itself)."""
    out = copy.deepcopy(single)
    if not vehicles:
        return out
    for pid, config in out["configById"].items():
        kind = pid.split("!")[0]
        if kind == "3D":
            _scene(config, vehicles)
        if isinstance(config.get("paths"), list):
            config["paths"] = [p for old in config["paths"] for p in _per_vehicle(old, vehicles)]
        for key in ("topicPath", "topicToRender"):  # one-topic panels: the first vehicle's
            if config.get(key) and not _is_run(config[key]):
                config[key] = vehicle_topic(vehicles[0], config[key])
    return out


def _topic(path: str) -> str:
    """The topic of a message path ('/plot/cmd.v_mps' -> '/plot/cmd')."""
    return path.split(".", 1)[0]


def _is_run(path: str) -> bool:
    return _topic(path) in FLEET_RUN_TOPICS


def _colour(i: int) -> str:
    return PALETTE[i % len(PALETTE)]


def _per_vehicle(path: dict[str, Any], vehicles: Sequence[str]) -> list[dict[str, Any]]:
    """A plot or state panel's series, once per vehicle (or as it is: the run's)."""
    if _is_run(path["value"]):
        return [path]
    out = []
    for i, vid in enumerate(vehicles):
        p = dict(path, value=vehicle_topic(vid, path["value"]))
        p["label"] = f"{vid} {path.get('label', '')}".rstrip()
        if "color" in path:
            p["color"] = _colour(i)
        out.append(p)
    return out


def _scene(config: dict[str, Any], vehicles: Sequence[str]) -> None:
    """The 3D panel: every vehicle's scene topics; its truth (pose, trail) in its colour, its
    estimate in the same colour half transparent; its frames hidden like the single's."""
    topics: dict[str, Any] = {}
    for topic, settings in config.get("topics", {}).items():
        if topic in FLEET_RUN_TOPICS:
            topics[topic] = settings
            continue
        alpha = "80" if topic.endswith("_est") else "ff"
        for i, vid in enumerate(vehicles):
            mine = dict(settings)
            if "color" in settings:
                mine["color"] = _colour(i) + alpha
            if "gradient" in settings:
                mine["gradient"] = [_colour(i) + alpha] * len(settings["gradient"])
            topics[vehicle_topic(vid, topic)] = mine
    config["topics"] = topics
    frames = {
        k: v
        for k, v in config.get("transforms", {}).items()
        if k.removeprefix("frame:") not in SINGLE_FRAMES
    }
    for vid in vehicles:
        for frame in (vid, f"{vid}_est"):
            frames[f"frame:{frame}"] = {"visible": False}
    config["transforms"] = frames
