"""The AUV mission's declared dataflow: its graph, periods from config, one factory per core,
and the declaration served by a live run (a real launch, queried from another process)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from helpers.launch_proc import REPO

from common.config.scenario import load_scenario
from common.messages import (
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    PathMsg,
    StateEstimate,
    TruthState,
    VehicleStatus,
    VelocityCommand,
)
from common.runtime.model.core import QueuePolicy, ServiceCore
from services.mission.dataflow import auv_dataflow

DEFAULT = REPO / "configs" / "default.toml"
WAIT_S = 45.0


def test_the_auv_graph_is_the_papers_loop() -> None:
    flow = auv_dataflow(load_scenario(DEFAULT)[0])
    assert flow.names == ("estimator", "planner", "sensor", "vehicle")
    links = {(lk.name, lk.input.msg_type, lk.input.policy) for lk in flow.links}
    assert links == {
        ("vehicle/truth->sensor", TruthState, QueuePolicy.NEWEST),
        ("sensor/nav->estimator", NavFix, QueuePolicy.ALL),
        ("sensor/obstacles->estimator", ObstacleDetections, QueuePolicy.ALL),
        ("estimator/state->planner", StateEstimate, QueuePolicy.NEWEST),
        ("estimator/tracks->planner", ObstacleTracks, QueuePolicy.NEWEST),
        ("planner/cmd->vehicle", VelocityCommand, QueuePolicy.ALL),
        # the one-way delay the vehicle measures on commands (issue 16)
        ("vehicle/status->planner", VehicleStatus, QueuePolicy.NEWEST),
    }
    # published for the record and monitors, read by no service
    assert {(o.stream, o.msg_type) for o in flow.service("planner").outputs} >= {("path", PathMsg)}
    assert flow.receivers[("planner", "path")] == ()


def test_periods_come_from_each_services_config() -> None:
    s, _ = load_scenario(
        DEFAULT,
        [
            "planner.period_s=0.25",
            "vehicle.period_s=0.02",
            "estimator.period_s=0.2",
            "sensor.nav_rate_hz=20.0",
        ],
    )
    flow = auv_dataflow(s)
    planner = flow.service("planner")
    assert (planner.period_s, planner.offset_s) == (0.25, 0.125)
    assert flow.service("vehicle").period_s == 0.02
    assert flow.service("estimator").period_s == 0.2
    assert flow.service("sensor").period_s == pytest.approx(1 / 20.0)


def test_every_factory_builds_its_core_from_the_scenario_alone() -> None:
    s, _ = load_scenario(DEFAULT)
    for service in auv_dataflow(s).services.values():
        assert isinstance(service.make_core(s), ServiceCore), service.name


def test_an_unknown_service_is_named_with_the_ones_there_are() -> None:
    flow = auv_dataflow(load_scenario(DEFAULT)[0])
    with pytest.raises(ValueError, match="unknown service 'sonar'; this mission has estimator"):
        flow.service("sonar")


def test_graph_prints_the_declaration_and_writes_dot_and_png(tmp_path: Path) -> None:
    res = subprocess.run(
        [
            sys.executable,
            "-m",
            "services.cli",
            "graph",
            str(DEFAULT),
            "--dot",
            str(tmp_path / "g.dot"),
            "--png",
            str(tmp_path / "g.png"),
        ],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 0, res.stderr
    assert "4 services, 7 links" in res.stdout
    assert "in   estimator/state        StateEstimate        newest" in res.stdout
    assert '"planner" -> "vehicle" [label="cmd: VelocityCommand' in (tmp_path / "g.dot").read_text()
    assert (tmp_path / "g.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_graph_needs_a_scenario_or_a_live_run() -> None:
    res = subprocess.run(
        [sys.executable, "-m", "services.cli", "graph"],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    assert res.returncode == 1
    assert "give a SCENARIO file, or --connect ENDPOINT" in res.stderr
