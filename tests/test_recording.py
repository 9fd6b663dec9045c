"""Recording runs end to end: a lockstep `launch --record` read back with the mcap package,
`tidelink metrics` against the run's own metrics.json, `tidelink replay` seen by a Watcher and
by `tidelink monitor` as a live run, recordings of runs that fail or are stopped. The remote
recorders of a realtime launch are tests/test_live_run.py's.

Every process is the real CLI in its own session (helpers/launch_proc.py); the tests wait on
the lines they print, on files and on exits, always with deadlines.
"""

from __future__ import annotations

import json
import os
import signal
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from helpers.launch_proc import Tidelink, judged_exit, kill_recorded
from helpers.recordings import frames, metrics_of, tidelink_metrics, without_wall
from mcap.reader import make_reader

from common.bus import Bus, Keys, Liveliness
from common.bus.watcher import WatchedFrame, Watcher
from common.config.bus import BusConfig
from common.config.scenario import load_scenario
from common.messages import RunEnd, decode
from common.runtime.model.inproc import run_inproc
from common.runtime.processes.children import free_port, wait_for_endpoint
from services.foxglove.view import PLANNER_PATH, POSE_TRUE, SCENE_STATIC
from services.recording.metrics import rebuild_record
from services.recording.reader import AliveEvent, read_recording

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"
WAIT_S = 90.0  # upper bound on any one wait; a run here takes a few seconds
SERVICES = {"estimator", "planner", "sensor", "vehicle"}


# -- a lockstep launch, recorded in-process ---------------------------------------------------
@pytest.fixture(scope="module")
def lockstep_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    out = tmp_path_factory.mktemp("lockstep") / "run"
    args = ("launch", str(SCENARIO), "--runtime", "lockstep", "--out", str(out), "--no-plot")
    try:
        with Tidelink(*args, "--record") as t:
            assert t.wait(WAIT_S) == judged_exit(out), t.stderr
            assert f"recording: {out / 'run.mcap'}" in t.stdout
        yield out
    finally:
        kill_recorded(out / "pids.json")


def test_a_recorded_lockstep_launch_reads_back_with_the_mcap_package(lockstep_run: Path) -> None:
    scenario, _ = load_scenario(SCENARIO, ['runtime.kind="lockstep"'])
    ref = run_inproc(scenario).record  # lockstep reproduces inproc message for message
    with (lockstep_run / "run.mcap").open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        (meta,) = list(reader.iter_metadata())
        got: dict[str, list[Any]] = {}
        for schema, channel, message in reader.iter_messages():
            if channel.metadata.get("tidelink") == "frame":
                assert channel.message_encoding == "msgpack"
                assert schema is not None and schema.encoding == "jsonschema"
                msg = decode(message.data)
                assert schema.name == f"tidelink.{type(msg).__name__}"
                assert message.sequence == msg.seq
                name = f"{channel.metadata['service']}/{channel.metadata['stream']}"
                assert channel.topic == f"/wire/{name}"
                got.setdefault(name, []).append(msg)
    assert meta.metadata["run"] == "small" and meta.metadata["vehicle"] == "auv1"
    assert json.loads(meta.metadata["scenario"]) == json.loads(
        (lockstep_run / "scenario.json").read_text()
    )
    (end,) = got.pop("runtime/end")
    run_metrics = metrics_of(lockstep_run / "metrics.json")
    assert isinstance(end, RunEnd)
    assert (end.reason, end.stamp, end.ticks) == (
        run_metrics["end_reason"],
        run_metrics["t_end_s"],
        run_metrics["ticks"],
    )
    assert set(got) == {f"{s}/{st}" for s, st in ref.keys()}
    for service, stream in ref.keys():
        # every message, in seq order, as the run recorded it (stats included)
        assert sorted(got[f"{service}/{stream}"], key=lambda m: m.seq) == ref.stream(
            service, stream
        )


def test_a_recording_carries_the_foxglove_view_of_the_run(lockstep_run: Path) -> None:
    with (lockstep_run / "run.mcap").open("rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None and summary.statistics is not None
    counts = summary.statistics.channel_message_counts
    view = {c.topic: c for c in summary.channels.values() if c.metadata["tidelink"] == "view"}
    assert {SCENE_STATIC, POSE_TRUE, PLANNER_PATH} <= set(view)
    for c in view.values():
        schema = summary.schemas[c.schema_id]
        assert (schema.encoding, c.message_encoding) in {
            ("protobuf", "protobuf"),
            ("jsonschema", "json"),
        }
    (truth,) = [c for c in summary.channels.values() if c.topic == "/wire/vehicle/truth"]
    assert counts[view[POSE_TRUE].id] == counts[truth.id]  # a pose per true state
    assert counts[view[SCENE_STATIC].id] == 1


def test_metrics_recomputed_from_a_lockstep_recording_equal_the_runs(lockstep_run: Path) -> None:
    recomputed = tidelink_metrics(lockstep_run / "run.mcap")
    own = metrics_of(lockstep_run / "metrics.json")
    assert "wall_s" in own and "wall_s" not in recomputed
    assert recomputed["trajectory_sha256"] == own["trajectory_sha256"]
    assert recomputed == without_wall(own)


def test_a_replay_is_a_live_run_to_a_watcher_in_another_process(
    lockstep_run: Path,
) -> None:
    rec = read_recording(lockstep_run / "run.mcap")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Tidelink("router", "--listen", endpoint):
        assert wait_for_endpoint(endpoint, WAIT_S), "the router did not listen"
        keys = Keys("again", rec.vehicle)
        with Bus(BusConfig(mode="client", connect=(endpoint,)), Keys("w", "w")) as bus:
            watcher = Watcher(bus, "again", rec.vehicle)
            watcher.start()
            with Tidelink(
                "replay", str(lockstep_run / "run.mcap"), "--connect", endpoint,
                "--speed", "2", "--as", "again",
            ) as replay:  # fmt: skip
                seen = _watch_until_gone(watcher, keys)
                assert replay.wait(WAIT_S) == 0, replay.stderr
    alive = {ev.key.rsplit("/", 1)[-1] for ev in seen.alive if ev.alive}
    assert alive == SERVICES | {"runtime"}
    assert seen.scenario == {
        **rec.scenario_raw,
        "run": {**rec.scenario_raw["run"], "name": "again"},
    }
    heard = [f for f in seen.frames if f.service != "runtime"]
    want = frames(rec)
    (end_frame,) = [k for k in want if k[0] == "runtime"]
    del want[end_frame]
    assert Counter((f.service, f.stream, f.payload, f.attachment) for f in heard) == want
    assert [decode(f.payload) for f in seen.frames if f.service == "runtime"] == [rec.end]
    # asked mid-run, the newest frame of each stream so far: each one a recorded frame
    assert seen.latest
    assert all((f.service, f.stream, f.payload, f.attachment) in want for f in seen.latest)


def test_a_replay_feeds_tidelink_monitor_as_a_live_run(lockstep_run: Path) -> None:
    rec = read_recording(lockstep_run / "run.mcap")
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    replay_args = ["--listen", endpoint, "--as", "shown", "--lead", "2"]
    with Tidelink("replay", str(lockstep_run / "run.mcap"), *replay_args) as replay:
        replay.wait_for(r"listening on", WAIT_S)
        with Tidelink("monitor", "--connect", endpoint, "--json", "--run", "shown") as mon:
            assert mon.wait(WAIT_S) == 0, mon.stderr  # it ends with the replayed run
        assert replay.wait(WAIT_S) == 0, replay.stderr
    lines = [json.loads(x) for x in mon.stdout.splitlines() if x.startswith("{")]
    events = [x for x in lines if x["type"] == "event"]
    assert any(e["event"] == "joined" and e["scenario"] for e in events), events
    (end,) = [e for e in events if e["event"] == "end"]
    assert rec.end is not None and end["text"].endswith(rec.end.reason)
    last = [x for x in lines if x["type"] == "update"][-1]
    assert last["run"] == "shown" and last["path"] is not None and last["pose"] is not None
    assert set(last["services"]) == SERVICES | {"runtime"}


@dataclass
class Seen:
    alive: list[Liveliness]
    frames: list[WatchedFrame]
    scenario: dict[str, Any] | None
    latest: list[WatchedFrame]


def _watch_until_gone(watcher: Watcher, keys: Keys) -> Seen:
    """Everything the watcher hears until the run's clock token has vanished and its RunEnd
    arrived (in either order: the RunEnd is a DATA_LOW copy, the token's end is not)."""
    seen = Seen([], [], None, [])
    gone = ended = False
    deadline = time.monotonic() + WAIT_S
    while time.monotonic() < deadline and not (gone and ended):
        ev = watcher.get(1.0)
        if isinstance(ev, Liveliness):
            seen.alive.append(ev)
            if ev.key == keys.alive("runtime"):
                gone = not ev.alive
                if ev.alive:
                    seen.scenario = watcher.scenario(keys)
        elif isinstance(ev, WatchedFrame):
            seen.frames.append(ev)
            ended = ev.service == "runtime"
            if len(seen.frames) == 100:
                seen.latest = watcher.latest(keys)  # while it plays
    assert gone, f"the replay's clock never left; heard {len(seen.frames)} frames"
    return seen


# -- recorders and launches that end early ----------------------------------------------------


def test_a_recorder_without_a_run_says_so_and_waits(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    out = tmp_path / "none.mcap"
    with Tidelink("router", "--listen", endpoint):
        assert wait_for_endpoint(endpoint, WAIT_S), "the router did not listen"
        with Tidelink("record", "--connect", endpoint, "-o", str(out)) as rec:
            rec.wait_for(r"no run yet; waiting for one", WAIT_S)
            assert rec.proc.poll() is None  # still waiting
            rec.signal(signal.SIGINT)
            assert rec.wait(WAIT_S) == 130
    assert "nothing recorded" in rec.stderr
    assert not out.exists()


TESTLOOP = """
[run]
mission = "testloop"
max_time_s = 16.0
[runtime]
time_scale = 4.0
"""


def test_metrics_of_a_recording_with_a_restarted_service_equal_the_runs(tmp_path: Path) -> None:
    scenario, out = tmp_path / "loop.toml", tmp_path / "run"
    scenario.write_text(TESTLOOP)
    args = ("launch", str(scenario), "--out", str(out), "--no-plot", "--record")
    try:
        with Tidelink(*args, "--restart", "filter=on-failure", "--backoff", "0.2") as t:
            t.wait_for(r"t=\s*[2-9]\.\d+ s of 16", WAIT_S)  # the loop runs
            (first,) = json.loads((out / "pids.json").read_text())["processes"]["filter"]
            os.kill(first, signal.SIGKILL)
            t.wait_for(r"service 'filter' rejoined at t=", WAIT_S)
            assert t.wait(WAIT_S) == 0, t.stderr
    finally:
        kill_recorded(out / "pids.json")
    rec = read_recording(out / "run.mcap")
    lives = [e.alive for e in rec.events if isinstance(e, AliveEvent) and e.service == "filter"]
    assert lives[:3] == [True, False, True]  # the recording saw it go and come back
    state = [f for f in rec.frames if (f.service, f.stream) == ("filter", "state")]
    seqs = [decode(f.payload).seq for f in state]
    assert any(b < a for a, b in zip(seqs, seqs[1:], strict=False))  # it numbered from 1 again
    # both lives kept apart, as the realtime driver keeps them (none taken for a repeat)
    record = rebuild_record(rec, ["ctrl", "filter", "plant", "sensor"])
    assert len(record.stream("filter", "state")) == len(state)
    assert tidelink_metrics(out / "run.mcap") == without_wall(metrics_of(out / "metrics.json"))


CRASHING = """
[run]
mission = "testloop"
max_time_s = 600.0
[run.mission_params]
crash_service = "filter"
crash_at_s = 1.0
"""


def test_a_launch_that_fails_or_is_stopped_still_closes_its_recording(tmp_path: Path) -> None:
    failing, stopped = tmp_path / "failing", tmp_path / "stopped"
    (tmp_path / "crash.toml").write_text(CRASHING)
    (tmp_path / "loop.toml").write_text(TESTLOOP)
    try:
        with Tidelink(
            "launch", str(tmp_path / "crash.toml"), "--out", str(failing), "--record", "--no-plot"
        ) as t:
            assert t.wait(WAIT_S) == 1  # the filter crashed: the run failed
        with Tidelink(
            "launch", str(tmp_path / "loop.toml"), "--out", str(stopped), "--record", "--no-plot"
        ) as t:
            t.wait_for(r"t=\s*[2-9]\.\d+ s of 16", WAIT_S)
            t.signal(signal.SIGINT)
            assert t.wait(WAIT_S) == 130
    finally:
        kill_recorded(failing / "pids.json")
        kill_recorded(stopped / "pids.json")
    crashed = read_recording(failing / "run.mcap")
    # closed, and the run's end says how it ended (a failed launch still ends its run)
    assert crashed.truncation is None
    assert crashed.end is not None and crashed.end.reason == "service_failed"
    assert crashed.frames
    interrupted = read_recording(stopped / "run.mcap")
    assert interrupted.truncation is None
    assert interrupted.end is not None and interrupted.end.reason == "interrupted"
