"""docs/foxglove/tidelink-layout.json: a Foxglove layout that shows what the view produces."""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from helpers.foxglove_view import REPO, short_run, view_all

from common.view import ViewMessage
from services.cli import main
from services.foxglove.dashboard import fleet_layout

LAYOUT = REPO / "docs" / "foxglove" / "tidelink-layout.json"
SCENE_SCHEMAS = {"foxglove.SceneUpdate", "foxglove.PoseInFrame", "foxglove.PosesInFrame"}


@pytest.fixture(scope="module")
def layout() -> dict[str, Any]:
    data = json.loads(LAYOUT.read_text())
    assert isinstance(data, dict)
    return data


def _firsts(messages: list[ViewMessage]) -> dict[str, ViewMessage]:
    """The first message of every topic."""
    out: dict[str, ViewMessage] = {}
    for vm in messages:
        out.setdefault(vm.topic, vm)
    return out


@pytest.fixture(scope="module")
def produced() -> dict[str, ViewMessage]:
    """The first message of every topic the view produced for a short run of default.toml."""
    return _firsts(view_all(*short_run()))


@pytest.fixture(scope="module")
def fleet() -> tuple[dict[str, Any], dict[str, ViewMessage]]:
    """The layout made for fleet4, and the first message of every topic its view produced
    in the first 3 s of an in-process run."""
    s, frames = short_run(3.0, REPO / "configs" / "fleet4.toml")
    layout = json.loads(LAYOUT.read_text())
    return fleet_layout(layout, [vid for vid, _ in s.members]), _firsts(view_all(s, frames))


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


def _check_reads(layout: dict[str, Any], produced: dict[str, ViewMessage]) -> None:
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


def _scene_topics(layout: dict[str, Any], produced: dict[str, ViewMessage]) -> dict[str, Any]:
    """The 3D panel's topics, checked to be the view's scene topics."""
    three_d = [c for pid, c in layout["configById"].items() if pid.startswith("3D!")]
    assert len(three_d) == 1
    assert three_d[0]["followTf"] == "world"  # every scene message is drawn in "world"
    topics: dict[str, Any] = three_d[0]["topics"]
    scene = {t for t, vm in produced.items() if vm.schema_name in SCENE_SCHEMAS}
    assert set(topics) == scene, "the 3D panel and the view's scene topics differ"
    return topics


def test_every_topic_and_field_the_layout_reads_is_produced_by_the_view(
    layout: dict[str, Any], produced: dict[str, ViewMessage]
) -> None:
    _check_reads(layout, produced)


def test_the_3d_panel_shows_every_scene_topic_of_the_view(
    layout: dict[str, Any], produced: dict[str, ViewMessage]
) -> None:
    topics = _scene_topics(layout, produced)
    visible = {t for t, s in topics.items() if s.get("visible")}
    assert {"/scene/static", "/planner/path", "/vehicle/pose_true", "/vehicle/pose_est"} <= visible


def test_a_fleets_layout_reads_every_vehicles_topics_and_nothing_its_view_lacks(
    fleet: tuple[dict[str, Any], dict[str, ViewMessage]],
) -> None:
    layout, produced = fleet
    _check_reads(layout, produced)
    topics = _scene_topics(layout, produced)
    colours = {topics[f"/{vid}/vehicle/pose_true"]["color"] for vid in ("auv1", "auv2", "auv3")}
    assert len(colours) == 3  # a colour per vehicle
    plot = layout["configById"]["Plot!goal"]["paths"]
    assert [p["value"] for p in plot][:4] == [
        f"/auv{i}/plot/truth.distance_to_goal_m" for i in (1, 2, 3, 4)
    ]
    assert plot[1]["label"] == "auv2 to goal (m)"
    assert layout["configById"]["Table!links"]["topicPath"] == "/links.links"  # the run's
    hidden = layout["configById"]["3D!tidelink"]["transforms"]
    assert "frame:auv" not in hidden and hidden["frame:auv4_est"] == {"visible": False}


def test_tidelink_foxglove_layout_for_prints_it(
    layout: dict[str, Any], capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main(["foxglove", "--layout-for", str(REPO / "configs" / "default.toml")]) == 0
    assert json.loads(capsys.readouterr().out) == layout  # one vehicle: the shipped layout
    assert main(["foxglove", "--layout-for", str(REPO / "configs" / "fleet_headon.toml")]) == 0
    paths = json.loads(capsys.readouterr().out)["configById"]["Plot!command"]["paths"]
    assert {p["value"].split("/")[1] for p in paths} == {"auv1", "auv2"}
    bad = tmp_path / "bad.toml"
    bad.write_text("[[vehicles]]\nid = 3\n")
    assert main(["foxglove", "--layout-for", str(bad)]) == 2
    assert "vehicles" in capsys.readouterr().err
