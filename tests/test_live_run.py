"""One realtime launch watched by every remote tool at once, each test reading its part.

The short mission is launched as a user does (`tidelink launch --record --listen`), its
vehicle joining from "another host" (`tidelink service vehicle`); around it, each a real
process of its own on the router: three remote recorders (one to the end, one SIGKILLed and
one SIGTERMed mid-run), a monitor that joins and is then SIGSTOPped for the rest of the run
(monitoring never steers: the run and every other watcher must not notice), a monitor that
joins mid-run, a Foxglove bridge with a WebSocket client that join mid-run, and a
`tidelink graph --connect` that asks the live run for its dataflow. Everything waits on
lines the processes print, on files and on exits, always with deadlines.
"""

from __future__ import annotations

import json
import math
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from helpers.foxglove_client import FoxgloveClient, schema_bytes
from helpers.launch_proc import REPO, Tidelink, judged_exit, kill_recorded
from helpers.protobuf_wire import Schemas
from helpers.recordings import (
    by_stream,
    frames,
    is_prefix,
    metrics_of,
    tidelink_metrics,
    without_wall,
)
from mcap.exceptions import McapError
from mcap.reader import NonSeekingReader, make_reader

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc
from common.runtime.processes.children import free_port
from common.runtime.run import write_outputs
from services.mission.dataflow import auv_dataflow
from services.recording.reader import read_recording

pytestmark = pytest.mark.slow

SHORT = REPO / "configs" / "experiments" / "scenarios" / "short.toml"
WAIT_S = 90.0  # upper bound on any one wait; the run takes ~15 s of wall time
# x2, not x4: the late joiners (monitor, bridge, Foxglove client) are started at mission time
# JOIN_LATE_AT_S and must be in before the run ends; at x4 that left ~6 s of wall time, which
# a loaded 2-core machine took to start the bridge alone (it joined an ended run)
SCALE = "2"
KILL_AT_BYTES = 128 * 1024  # the killed recorder's file by then holds several chunks
JOIN_LATE_AT_S = 4.0  # mission time the late monitor, bridge and graph query join at
PROTOBUF_TOPICS = {
    "/vehicle/pose_true": "foxglove.PoseInFrame",
    "/vehicle/pose_est": "foxglove.PoseInFrame",
    "/planner/path": "foxglove.SceneUpdate",
    "/scene/static": "foxglove.SceneUpdate",
    "/scene/tracks": "foxglove.SceneUpdate",
}


@dataclass
class LiveRun:
    """The launch's folder and every watcher's process and findings."""

    out: Path  # metrics.json, run.mcap (the launch's own recording), run.png, logs/
    launch: Tidelink
    recorders: dict[str, Tidelink]  # full, killed, stopped
    files: dict[str, Path]
    killed_mid_run: bool  # the launch still ran when two recorders were stopped
    frozen: Tidelink  # the SIGSTOPped monitor
    late: Tidelink  # the monitor that joined mid-run
    joined: dict[str, Any]  # its "joined" event
    bridge: Tidelink
    bridge_joined_streams: int
    graph: subprocess.CompletedProcess[str]
    fox: dict[str, Any] = field(default_factory=dict)  # what the Foxglove client decoded


def _decode(client: FoxgloveClient, topic: str, index: int = -1) -> dict[str, Any]:
    ch = client.channel(topic)
    return Schemas(schema_bytes(ch)).decode(f".{ch['schemaName']}", client.on(topic)[index].data)


def _mission_time(t: Tidelink, at_least: float) -> None:
    """Wait for the launcher's progress line past `at_least` mission seconds."""
    mark = 0
    while float(t.wait_for(r"t=\s*([0-9.]+) s of", WAIT_S, start=mark)[1]) < at_least:
        mark = len(t.err)


def _grow(path: Path, size: int, launch: Tidelink, who: Tidelink) -> None:
    deadline = time.monotonic() + WAIT_S
    while not path.exists() or path.stat().st_size < size:
        assert time.monotonic() < deadline, who.stderr
        assert launch.proc.poll() is None, launch.stderr
        time.sleep(0.05)  # polling a file another process writes


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[LiveRun]:
    d = tmp_path_factory.mktemp("live")
    out, endpoint, ws_port = d / "run", f"tcp/127.0.0.1:{free_port()}", free_port()
    files = {name: d / f"{name}.mcap" for name in ("full", "killed", "stopped")}
    with ExitStack() as stack:
        stack.callback(kill_recorded, out / "pids.json")
        launch = stack.enter_context(
            Tidelink(
                "launch", str(SHORT), "--out", str(out), "--record", "--listen", endpoint,
                "--only", "estimator,planner,sensor", "--time-scale", SCALE,
            )
        )  # fmt: skip
        launch.wait_for(r"waiting for vehicle to join", WAIT_S)
        rec = {
            name: stack.enter_context(Tidelink("record", "--connect", endpoint, "-o", str(f)))
            for name, f in files.items()
        }
        frozen = stack.enter_context(
            Tidelink("monitor", "--connect", endpoint, "--json", "--every", "0.1")
        )
        for r in rec.values():
            r.wait_for(r"recording run short/auv1", WAIT_S)
        frozen.wait_for(r'"event": "joined"', WAIT_S, stdout=True)
        frozen.signal(signal.SIGSTOP)  # it stops reading: its socket fills, the tap drops
        stack.callback(frozen.signal, signal.SIGCONT)
        # the vehicle joins from "another host" once every watcher listens: they see it all
        stack.enter_context(
            Tidelink("service", "vehicle", str(SHORT), "--connect", endpoint, "--time-scale", SCALE)
        )
        _grow(files["killed"], KILL_AT_BYTES, launch, rec["killed"])
        killed_mid_run = launch.proc.poll() is None
        os.killpg(rec["killed"].proc.pid, signal.SIGKILL)
        rec["stopped"].signal(signal.SIGTERM)

        _mission_time(launch, JOIN_LATE_AT_S)  # the path was planned at t = 0: join late
        late = stack.enter_context(
            Tidelink("monitor", "--connect", endpoint, "--json", "--every", "0.25")
        )
        bridge = stack.enter_context(
            Tidelink("foxglove", "--connect", endpoint, "--port", str(ws_port))
        )
        graph = subprocess.run(
            [sys.executable, "-m", "services.cli", "graph", "--connect", endpoint, "--json",
             "--timeout", "10"],
            cwd=REPO, capture_output=True, text=True, timeout=WAIT_S, check=False,
        )  # fmt: skip
        bridge.wait_for(f"serving Foxglove on ws://127.0.0.1:{ws_port}", WAIT_S)
        # the app leaves before the bridge is stopped (closing on a stopped server waits)
        with FoxgloveClient(f"ws://127.0.0.1:{ws_port}") as client:
            streams = bridge.wait_for(
                r"watching run short/auv1 \(joined with the newest frame of (\d+) streams\)", WAIT_S
            )
            client.wait_until(
                lambda: all(client.on(t) for t in PROTOBUF_TOPICS), WAIT_S, "scene messages"
            )
            joined = json.loads(late.wait_for(r'"event": "joined"', WAIT_S, stdout=True).string)
            fox: dict[str, Any] = {
                "subprotocol": client.subprotocol,
                "server": client.server_infos[0]["name"],
                "channels": {t: client.channel(t) for t in PROTOBUF_TOPICS},
                "pose": _decode(client, "/vehicle/pose_true"),
                "path": _decode(client, "/planner/path"),
                "static": _decode(client, "/scene/static"),
                "tracks": _decode(client, "/scene/tracks"),
            }
            while launch.proc.poll() is None:
                client.pump(0.2)  # reading the socket as the app does
            launch.wait(WAIT_S)
            bridge.wait_for("run short/auv1 is over", WAIT_S)
            client.wait_until(lambda: bool(client.on("/run/end")), WAIT_S, "/run/end")
            fox["end"] = json.loads(client.on("/run/end")[-1].data)
            client.pump(0.5)
            fox["connected_after_the_run"] = not client.closed and bridge.proc.poll() is None
        bridge.signal(signal.SIGTERM)
        late.wait(WAIT_S)
        for r in rec.values():
            r.wait(WAIT_S)
        bridge.wait(WAIT_S)
        frozen.signal(signal.SIGCONT)
        yield LiveRun(
            out, launch, rec, files, killed_mid_run, frozen, late, joined, bridge,
            int(streams.group(1)), graph, fox,
        )  # fmt: skip


# -- the run itself --------------------------------------------------------------------------


def test_the_launch_reaches_its_goal_with_a_frozen_watcher_on_the_bus(live: LiveRun) -> None:
    m = metrics_of(live.out / "metrics.json")
    summary = {k: v for k, v in m.items() if k != "link_stats"}
    assert live.launch.proc.returncode == judged_exit(live.out), live.launch.stderr
    assert m["runtime"] == "realtime" and m["end_reason"] == "goal", summary
    assert m["reached_goal"] is True and m["collisions"] == 0, summary
    cmd = m["link_stats"]["planner/cmd->vehicle"]
    # 5 % loss on ~270 commands: none lost has a probability of about 1e-6
    assert cmd["dropped_loss"] > 0
    drops = cmd["dropped_loss"] + cmd["dropped_outage"] + cmd["dropped_queue"]
    assert cmd["sent"] == cmd["delivered"] + drops


def test_a_launch_writes_the_metrics_of_tidelink_run_its_plot_and_logs(
    live: LiveRun, tmp_path: Path
) -> None:
    # the key set does not depend on how far a run got: a 4 s inproc run names them all
    s, _ = load_scenario(SHORT, ["run.max_time_s=4"])
    keys = set(write_outputs(run_inproc(s), s, tmp_path / "inproc", wall_s=0.0).to_json())
    assert set(metrics_of(live.out / "metrics.json")) == keys
    png = (live.out / "run.png").read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 20_000
    logs = {p.name for p in (live.out / "logs").iterdir()}
    # the vehicle ran elsewhere: its log is its host's
    assert logs >= {"estimator.log", "planner.log", "sensor.log", "router.log", "launch.log"}
    assert "metrics:" in live.launch.stdout and "plot:" in live.launch.stdout


# -- remote recorders ------------------------------------------------------------------------


def test_a_remote_recording_holds_every_frame_of_the_run(live: LiveRun) -> None:
    full = live.recorders["full"]
    assert full.proc.returncode == 0, full.stderr
    assert "lost: none" in full.stdout
    assert "the run: goal at t=" in full.stdout
    remote, local = read_recording(live.files["full"]), read_recording(live.out / "run.mcap")
    assert remote.truncation is None and local.truncation is None
    assert (remote.recorder, local.recorder) == ("record", "launch")
    assert len(local.frames) > 1000
    assert frames(remote) == frames(local)  # byte for byte, attachments included
    assert remote.end == local.end is not None


def test_metrics_recomputed_from_realtime_recordings_equal_the_runs(live: LiveRun) -> None:
    own = without_wall(metrics_of(live.out / "metrics.json"))
    assert tidelink_metrics(live.out / "run.mcap") == own
    assert tidelink_metrics(live.files["full"]) == own


def test_a_recorder_killed_mid_run_leaves_a_file_read_up_to_its_last_chunk(
    live: LiveRun,
) -> None:
    assert live.killed_mid_run
    assert live.recorders["killed"].proc.returncode == -signal.SIGKILL
    path = live.files["killed"]
    # the mcap package's own reader, front to back, up to where the file stops
    got: list[tuple[str, bytes]] = []
    with path.open("rb") as fh:
        try:
            for _, channel, message in NonSeekingReader(fh).iter_messages(log_time_order=False):
                if channel.metadata.get("tidelink") == "frame":
                    meta = channel.metadata
                    got.append((f"{meta['service']}/{meta['stream']}", message.data))
        except McapError:
            pass  # the unfinished chunk at the end
    assert len(got) >= 100
    rec = read_recording(path)
    assert rec.truncation is not None and rec.end is None
    assert [(f"{f.service}/{f.stream}", f.payload) for f in rec.frames] == got
    # each stream's frames are the first ones of the full recording: nothing torn or skipped
    full = read_recording(live.files["full"])
    assert is_prefix(by_stream(rec.frames), by_stream(full.frames))
    assert len(rec.frames) < len(full.frames)


def test_a_recorder_stopped_by_sigterm_closes_its_file(live: LiveRun) -> None:
    assert live.killed_mid_run
    stopped = live.recorders["stopped"]
    assert stopped.proc.returncode == 130, stopped.stderr
    assert "the run: stopped by SIGTERM" in stopped.stdout
    with live.files["stopped"].open("rb") as fh:
        assert make_reader(fh).get_summary() is not None  # closed: summary and footer
    rec = read_recording(live.files["stopped"])
    assert rec.truncation is None
    full = read_recording(live.files["full"])
    assert is_prefix(by_stream(rec.frames), by_stream(full.frames))
    assert 0 < len(rec.frames) < len(full.frames)


# -- monitors, the Foxglove bridge, the dataflow query ---------------------------------------


def test_a_monitor_joining_mid_run_gets_the_path_in_force_at_once_and_exits_at_the_end(
    live: LiveRun,
) -> None:
    joined, late = live.joined, live.late
    # the path is not re-sent until a replan: only the late-join query can give it
    assert joined["path_id"] is not None and joined["scenario"] is True, joined
    assert joined["joined_in_s"] < 1.0, joined
    assert late.proc.returncode == 0, late.stderr  # it exits by itself when the run ends
    lines = [json.loads(x) for x in late.stdout.splitlines() if x.startswith("{")]
    updates = [x for x in lines if x["type"] == "update"]
    assert updates and updates[0]["path"]["path_id"] >= 1
    assert updates[0]["mode"] in ("RUN", "HOLD")  # from the latest status, at join
    assert updates[0]["to_goal_m"] is not None
    assert {"sensor", "estimator", "planner", "vehicle", "runtime"} <= set(updates[0]["services"])
    m = metrics_of(live.out / "metrics.json")
    assert updates[-1]["end"]["reason"] == m["end_reason"]
    assert len([x for x in lines if x["type"] == "event" and x["event"] == "end"]) == 1
    # polling by default, it still hears every event stream: no replan falls between polls
    # (ids count the paths planned; those replaced before the join are not its events)
    paths = {x["path_id"] for x in lines if x["type"] == "event" and x["event"] == "path"}
    assert paths == set(range(joined["path_id"], m["replans"] + 1)), paths


def test_a_foxglove_client_that_joined_late_gets_the_scene_and_the_runs_end(
    live: LiveRun,
) -> None:
    s, _ = load_scenario(SHORT)
    fox = live.fox
    assert fox["subprotocol"] == "foxglove.sdk.v1" and fox["server"] == "tidelink"
    # truth, status, nav, obstacles, state, tracks, path, cmd (+ stats)
    assert live.bridge_joined_streams >= 8, live.bridge.stderr
    for topic, schema_name in PROTOBUF_TOPICS.items():
        ch = fox["channels"][topic]
        assert (ch["encoding"], ch["schemaName"]) == ("protobuf", schema_name)
    pose = fox["pose"]
    p, q = pose["pose"]["position"], pose["pose"]["orientation"]
    area = s.world.area
    assert pose["frame_id"] == "world" and pose["timestamp"]["seconds"] > 0  # past the start
    assert area.x_min_m <= p["x"] <= area.x_max_m and area.y_min_m <= p["y"] <= area.y_max_m
    assert q["x"] == q["y"] == 0.0 and math.hypot(q["z"], q["w"]) == pytest.approx(1.0)
    # the path was planned before the bridge existed: it came by late join, to the goal
    end = {e["id"]: e for e in fox["path"]["entities"]}["path"]["lines"][0]["points"][-1]
    assert math.hypot(end["x"] - s.world.goal.x_m, end["y"] - s.world.goal.y_m) < 1e-6
    static = {e["id"] for e in fox["static"]["entities"]}
    assert {f"obstacle/{c.id}" for c in s.world.circles} <= static
    assert all(e["id"].startswith("track/") for e in fox["tracks"]["entities"])
    assert fox["end"]["reason"] == "goal"
    # the run is over, the bridge is not: the client stays connected until it is stopped
    assert fox["connected_after_the_run"]
    assert live.bridge.proc.returncode == 0, live.bridge.stderr
    assert "stopping on SIGTERM" in live.bridge.stderr


def test_a_live_run_serves_its_dataflow_to_a_tool_without_the_scenario(live: LiveRun) -> None:
    assert live.graph.returncode == 0, live.graph.stderr
    (line,) = live.graph.stdout.splitlines()
    got = json.loads(line)
    assert got["title"] == "dataflow of live run tidelink/short/auv1/dataflow"
    expected = auv_dataflow(load_scenario(SHORT)[0]).describe()
    assert {k: got[k] for k in expected} == expected


def test_a_sigstopped_monitor_holds_nothing_up_and_carries_on_after(live: LiveRun) -> None:
    # it was stopped the whole run; woken after its end it finds the run over and leaves
    live.frozen.signal(signal.SIGTERM)
    assert live.frozen.wait(WAIT_S) == 0, live.frozen.stderr
