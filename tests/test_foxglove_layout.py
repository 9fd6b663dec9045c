"""docs/foxglove/tidelink-layout.json: a Foxglove layout that shows what the view produces."""

from __future__ import annotations

import json
from collections.abc import Iterator
from typing import Any

import pytest
from helpers.foxglove_view import REPO, short_run, view_all

from services.foxglove.view import ViewMessage

LAYOUT = REPO / "docs" / "foxglove" / "tidelink-layout.json"
SCENE_SCHEMAS = {"foxglove.SceneUpdate", "foxglove.PoseInFrame", "foxglove.PosesInFrame"}


@pytest.fixture(scope="module")
def layout() -> dict[str, Any]:
    data = json.loads(LAYOUT.read_text())
    assert isinstance(data, dict)
    return data


@pytest.fixture(scope="module")
def produced() -> dict[str, ViewMessage]:
    """The first message of every topic the view produced for a short run of default.toml."""
    out: dict[str, ViewMessage] = {}
    for vm in view_all(*short_run()):
        out.setdefault(vm.topic, vm)
    return out


def _panel_ids(node: Any) -> Iterator[str]:
    """The panel ids of a mosaic layout tree (a panel id, or a split with first/second)."""
    if isinstance(node, str):
        yield node
        return
    assert node["direction"] in ("row", "column") and 0 < node["splitPercentage"] < 100
    yield from _panel_ids(node["first"])
    yield from _panel_ids(node["second"])


def _paths(config: dict[str, Any]) -> list[str]:
    """Every message path a panel reads: 'topic' or 'topic.field...'."""
    out = [p["value"] for p in config.get("paths", [])]
    out += [config[k] for k in ("topicPath", "topicToRender") if config.get(k)]
    return out


def test_the_layout_is_an_importable_foxglove_layout(layout: dict[str, Any]) -> None:
    assert set(layout) >= {"configById", "layout", "globalVariables", "userNodes"}
    ids = list(_panel_ids(layout["layout"]))
    assert len(ids) == len(set(ids)) and set(ids) == set(layout["configById"])
    kinds = {pid.split("!")[0] for pid in ids}
    assert kinds >= {"3D", "Plot", "Table", "StateTransitions"}


def test_every_topic_and_field_the_layout_reads_is_produced_by_the_view(
    layout: dict[str, Any], produced: dict[str, ViewMessage]
) -> None:
    for pid, config in layout["configById"].items():
        for path in _paths(config):
            topic, _, field = path.partition(".")
            assert topic in produced, f"{pid} reads {topic}, which the view never produces"
            vm = produced[topic]
            if field:
                assert vm.message_encoding == "json", f"{pid}: {path} on a non-JSON topic"
                name = field.split(".")[0].split("[")[0]
                props = json.loads(vm.schema)["properties"]
                assert name in props, f"{pid}: {topic} has no field {name!r}"


def test_the_3d_panel_shows_every_scene_topic_of_the_view(
    layout: dict[str, Any], produced: dict[str, ViewMessage]
) -> None:
    three_d = [c for pid, c in layout["configById"].items() if pid.startswith("3D!")]
    assert len(three_d) == 1
    topics = three_d[0]["topics"]
    scene = {t for t, vm in produced.items() if vm.schema_name in SCENE_SCHEMAS}
    assert set(topics) == scene, "the 3D panel and the view's scene topics differ"
    visible = {t for t, s in topics.items() if s.get("visible")}
    assert {"/scene/static", "/planner/path", "/vehicle/pose_true", "/vehicle/pose_est"} <= visible
    assert three_d[0]["followTf"] == "world"  # every scene message is drawn in "world"
