"""The MCAP recording format without a bus: what RunWriter writes, read back by the mcap
package and by our reader; files cut short, not MCAP, or from a newer wire version; lost-frame
counting; a record rebuilt from a recording."""

from __future__ import annotations

import dataclasses
import json
import shutil
from pathlib import Path

import msgspec
import pytest
from mcap.reader import make_reader
from mcap.writer import Writer

from common.bus.gaps import SeqGaps
from common.config.scenario import load_scenario
from common.messages import (
    WIRE_VERSION,
    Message,
    NavFix,
    RunEnd,
    TruthState,
    encode,
    encode_routing,
)
from services.cli import main
from services.recording import layout
from services.recording.layout import stream_types
from services.recording.metrics import rebuild_record
from services.recording.reader import (
    AliveEvent,
    RecordedEvent,
    RecordedFrame,
    Recording,
    RecordingError,
    read_recording,
)
from services.recording.writer import RunInfo, RunWriter

ROOT = Path(__file__).resolve().parents[1]
SCENARIO = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"
T0 = 1_800_000_000.0  # a wall time (Unix s) for the frames


def _nav(seq: int) -> NavFix:
    return NavFix(
        stamp=seq * 0.2,
        x=float(seq),
        y=2.0,
        heading=0.1,
        speed=1.0,
        std_xy=0.5,
        std_heading=0.01,
        std_speed=0.1,
        source="sensor",
        seq=seq,
    )


def _truth(seq: int) -> TruthState:
    return TruthState(
        stamp=seq * 0.1, x=float(seq), y=0.0, theta=0.0, v=1.0, w=0.0, source="vehicle", seq=seq
    )


def _written(n: int) -> list[tuple[str, str, bytes, bytes | None, float]]:
    """n frames on two streams (nav with routing attachments, truth without), then a RunEnd."""
    out: list[tuple[str, str, bytes, bytes | None, float]] = []
    for i in range(1, n + 1):
        att = encode_routing(i, {"estimator": (i * 1000,)})
        out.append(("sensor", "nav", encode(_nav(i)), att, T0 + i * 0.01))
        out.append(("vehicle", "truth", encode(_truth(i)), None, T0 + i * 0.01 + 0.005))
    end = RunEnd(stamp=n * 0.2, reason="goal", ticks=n, source="runtime", seq=1)
    out.append(("runtime", "end", encode(end), None, T0 + n * 0.01 + 0.01))
    return out


class FakeClock:
    """The writer's flush clock, advanced by hand."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def _writer(path: Path, clock: FakeClock | None = None) -> RunWriter:
    scenario, raw = load_scenario(SCENARIO)
    info = RunInfo(run="small", vehicle="auv1", scenario_raw=raw, recorder="test")
    return RunWriter(path, info, stream_types(scenario), clock=clock or FakeClock())


def _write(path: Path, n: int = 50) -> list[tuple[str, str, bytes, bytes | None, float]]:
    frames = _written(n)
    w = _writer(path)
    w.alive("sensor", True, T0)
    for f in frames:
        w.frame(*f)
    w.alive("sensor", False, T0 + 10)
    w.close()
    return frames


def test_a_recording_reads_back_frame_for_frame(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    frames = _write(path)
    rec = read_recording(path)
    assert rec.truncation is None
    assert (rec.run, rec.vehicle, rec.recorder) == ("small", "auv1", "test")
    assert rec.scenario_raw == load_scenario(SCENARIO)[1]
    got = [(f.service, f.stream, f.payload, f.attachment, round(f.wall * 1e9)) for f in rec.frames]
    assert got == [(s, st, p, a, round(w * 1e9)) for s, st, p, a, w in frames]
    alive = [e for e in rec.events if isinstance(e, AliveEvent)]
    assert [(e.service, e.alive) for e in alive] == [("sensor", True), ("sensor", False)]
    assert rec.end == RunEnd(stamp=10.0, reason="goal", ticks=50, source="runtime", seq=1)


def test_the_mcap_package_reads_its_channels_schemas_and_metadata(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    frames = _write(path, n=30)
    with path.open("rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        assert summary is not None
        channels = {c.topic: c for c in summary.channels.values()}
        assert set(channels) == {
            "/wire/sensor/nav",
            "/wire/sensor/nav/routing",
            "/wire/vehicle/truth",
            "/wire/runtime/end",
            "/alive",
        }
        for topic in ("/wire/sensor/nav", "/wire/vehicle/truth", "/wire/runtime/end"):
            assert channels[topic].message_encoding == "msgpack"
        names = {c.topic: summary.schemas[c.schema_id].name for c in channels.values()}
        assert names["/wire/sensor/nav"] == "tidelink.NavFix"
        assert names["/wire/vehicle/truth"] == "tidelink.TruthState"
        assert names["/wire/runtime/end"] == "tidelink.RunEnd"
        schema = summary.schemas[channels["/wire/sensor/nav"].schema_id]
        assert schema.encoding == "jsonschema"
        doc = json.loads(schema.data)
        assert doc["prefixItems"][0] == {"const": WIRE_VERSION}
        fields = set(doc["$defs"]["NavFix"]["properties"])
        assert fields == {"type", *(f.name for f in msgspec.structs.fields(NavFix))}
        counts = summary.statistics.channel_message_counts  # type: ignore[union-attr]
        assert counts[channels["/wire/sensor/nav"].id] == 30
        assert counts[channels["/wire/sensor/nav/routing"].id] == 30
        assert counts[channels["/wire/vehicle/truth"].id] == 30
        (meta,) = list(reader.iter_metadata())
        assert meta.name == "tidelink"
        assert meta.metadata["wire_version"] == str(WIRE_VERSION)
        assert (meta.metadata["run"], meta.metadata["vehicle"]) == ("small", "auv1")
        assert json.loads(meta.metadata["scenario"]) == load_scenario(SCENARIO)[1]
        navs = list(reader.iter_messages(topics=["/wire/sensor/nav"]))
    # raw wire bytes, MCAP sequence = the message's seq, log time = the tap's wall time
    sent = [f for f in frames if f[1] == "nav"]
    assert [m.data for _, _, m in navs] == [f[2] for f in sent]
    assert [m.sequence for _, _, m in navs] == list(range(1, 31))
    assert [m.log_time for _, _, m in navs] == [round(f[4] * 1e9) for f in sent]


def test_a_writer_that_dies_leaves_every_flushed_chunk_readable(tmp_path: Path) -> None:
    path, cut = tmp_path / "run.mcap", tmp_path / "killed.mcap"
    clock = FakeClock()
    w = _writer(path, clock)
    frames = _written(200)[:-1]  # the run never got to its end
    for f in frames[:300]:
        w.frame(*f)
    clock.t = 1.0
    w.flush_if_due()  # on disk now
    for f in frames[300:310]:
        w.frame(*f)  # less than a chunk, in the writer's memory only: lost with it
    shutil.copy(path, cut)  # what a SIGKILL would leave: the writer is never closed
    rec = read_recording(cut)
    assert rec.truncation is not None
    assert rec.truncation.read_bytes == rec.truncation.size_bytes  # it ends on a whole chunk
    assert "not closed" in rec.truncation.describe(cut)
    assert [f.payload for f in rec.frames] == [f[2] for f in frames[:300]]
    assert rec.end is None
    w.close()


@pytest.mark.parametrize("keep", [0.97, 0.8, 0.6, 0.45])
def test_a_file_cut_short_reads_up_to_its_last_whole_chunk(tmp_path: Path, keep: float) -> None:
    path, cut = tmp_path / "run.mcap", tmp_path / "cut.mcap"
    clock = FakeClock()
    w = _writer(path, clock)
    frames = _written(600)
    for i, f in enumerate(frames):
        w.frame(*f)
        if i % 100 == 99:
            clock.t += 1.0
            w.flush_if_due()
    w.close()
    data = path.read_bytes()
    cut.write_bytes(data[: int(len(data) * keep)])
    rec = read_recording(cut)
    assert rec.truncation is not None
    assert 0 < rec.truncation.read_bytes < rec.truncation.size_bytes == int(len(data) * keep)
    text = rec.truncation.describe(cut)
    assert str(cut) in text and "truncated" in text
    # a prefix of what was written, each frame whole
    n = len(rec.frames)
    assert n > 0
    assert [(f.payload, f.attachment) for f in rec.frames] == [(f[2], f[3]) for f in frames[:n]]


def test_a_file_cut_before_its_metadata_names_the_file(tmp_path: Path) -> None:
    path, cut = tmp_path / "run.mcap", tmp_path / "cut.mcap"
    _write(path)
    cut.write_bytes(path.read_bytes()[:40])
    with pytest.raises(RecordingError, match=f"{cut}: cut short before its tidelink metadata"):
        read_recording(cut)


@pytest.mark.parametrize(
    ("content", "why"),
    [
        (b"", "not an MCAP file \\(it is empty\\)"),
        (b"t,x,y\n0,1,2\n", "not an MCAP file \\(it does not start with MCAP's magic bytes\\)"),
    ],
)
def test_what_is_not_mcap_is_refused_naming_the_file(
    tmp_path: Path, content: bytes, why: str
) -> None:
    path = tmp_path / "run.mcap"
    path.write_bytes(content)
    with pytest.raises(RecordingError, match=f"{path}: {why}"):
        read_recording(path)


def test_a_missing_file_is_refused_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.mcap"
    with pytest.raises(RecordingError, match=f"{path}: cannot read it"):
        read_recording(path)


def _mcap_with_metadata(path: Path, meta: dict[str, str] | None) -> None:
    """An MCAP file written with the mcap package alone (an independent writer)."""
    with path.open("wb") as fh:
        w = Writer(fh)
        w.start(profile="tidelink", library="test")
        if meta is not None:
            w.add_metadata("tidelink", meta)
        w.finish()


@pytest.mark.parametrize(
    ("version", "why"),
    [
        (WIRE_VERSION + 1, f"newer than this build's {WIRE_VERSION}"),
        (WIRE_VERSION - 1, f"this build decodes only version {WIRE_VERSION}"),
    ],
)
def test_another_wire_version_is_refused_naming_the_file(
    tmp_path: Path, version: int, why: str
) -> None:
    path = tmp_path / "future.mcap"
    meta = {"wire_version": str(version), "run": "r", "vehicle": "v", "scenario": "{}"}
    _mcap_with_metadata(path, meta)
    with pytest.raises(RecordingError, match=f"{path}: recorded with wire version {version}"):
        read_recording(path)
    with pytest.raises(RecordingError, match=why):
        read_recording(path)


def test_an_mcap_file_that_is_no_recording_is_refused_naming_it(tmp_path: Path) -> None:
    path = tmp_path / "other.mcap"
    _mcap_with_metadata(path, None)
    with pytest.raises(RecordingError, match=f"{path}: an MCAP file, but not a tidelink"):
        read_recording(path)


def test_the_cli_reports_bad_input_naming_the_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "notes.mcap"
    path.write_text("not a recording")
    for command in ("metrics", "replay"):
        assert main([command, str(path)]) == 1
        err = capsys.readouterr().err
        assert f"tidelink: error: {path}: not an MCAP file" in err


def test_seq_gaps_count_what_a_watcher_lost() -> None:
    g = SeqGaps()
    for seq in (5, 6, 7, 10, 11, 11, 12):  # joined at 5; 8 and 9 lost; 11 heard twice
        g.see("a", seq)
    for seq in (1, 2, 3, 1, 2, 4):  # restarted after 3; 3 of its new life lost
        g.see("b", seq)
    assert dict(g.lost) == {"a": 2, "b": 1}
    assert g.first == {"a": 5, "b": 1}
    assert dict(g.restarts) == {"b": 1}
    assert g.total == 3


def _frame(service: str, stream: str, msg: Message, wall: float) -> RecordedFrame:
    return RecordedFrame(service, stream, encode(msg), None, wall)


def test_a_restarted_service_is_renumbered_as_the_realtime_driver_does(tmp_path: Path) -> None:
    events: list[RecordedEvent] = [
        AliveEvent("vehicle", True, 0.0),
        *(_frame("vehicle", "truth", _truth(i), i) for i in (1, 2, 3)),
        AliveEvent("vehicle", False, 4.0),
        AliveEvent("vehicle", True, 5.0),  # restarted: numbers from 1 again
        *(_frame("vehicle", "truth", _truth(i), 5 + i) for i in (1, 2)),
        _frame("runtime", "end", RunEnd(stamp=1.0, reason="goal", ticks=0), 9.0),
    ]
    rec = Recording(
        path=tmp_path / "r.mcap",
        run="r",
        vehicle="v",
        recorder="test",
        scenario_raw={},
        events=tuple(events),
        truncation=None,
    )
    record = rebuild_record(rec, ["vehicle"])
    assert [m.seq for m in record.stream("vehicle", "truth")] == [1, 2, 3, 4, 5]
    assert record.keys() == [("vehicle", "truth")]  # the clock's RunEnd is not the run's
    # without the liveliness, the new life's messages would be taken for repeats
    no_alive = dataclasses.replace(
        rec, events=tuple(e for e in events if not isinstance(e, AliveEvent))
    )
    assert len(rebuild_record(no_alive, ["vehicle"]).stream("vehicle", "truth")) == 3


def test_layout_names_channels_and_types_every_stream() -> None:
    scenario, _ = load_scenario(SCENARIO)
    types = stream_types(scenario)
    assert types[("sensor", "nav")] is NavFix
    assert types[("runtime", "end")] is RunEnd
    assert {k for k in types if k[1] == "stats"} == {
        (s, "stats") for s in ("estimator", "planner", "sensor", "vehicle")
    }
    assert layout.frame_topic("sensor", "nav") == "/wire/sensor/nav"
    assert layout.routing_topic("sensor", "nav") == "/wire/sensor/nav/routing"


def test_a_full_disk_closes_the_recording_at_its_last_whole_chunk(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """ENOSPC mid-run: the file is cut back to its last whole chunk and closed there (MCAP's
    end records: it reads as a complete file), the error is kept, later frames are counted
    lost, and nothing raises (a recorder's disk must not end the run)."""
    import errno

    from services.recording import writer as writer_module

    path = tmp_path / "run.mcap"
    clock = FakeClock()
    w = _writer(path, clock)
    frames = _written(200)  # 401 frames: nav, truth, ..., the RunEnd
    for f in frames[:100]:
        w.frame(*f)
    clock.t += 1.0
    w.flush_if_due()  # these 100 are on disk

    def full(fd: int, data: memoryview) -> int:
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(writer_module, "_os_write", full)
    for f in frames[100:]:
        w.frame(*f)
        clock.t += 0.3
        w.flush_if_due()
    w.close()
    assert w.failed is not None and w.failed.errno == errno.ENOSPC
    assert (w.frames, w.lost) == (100, len(frames) - 100)
    rec = read_recording(path)
    assert rec.truncation is None  # closed: not a file cut short
    got = [(f.service, f.stream, f.payload, f.attachment) for f in rec.frames]
    assert got == [f[:4] for f in frames[:100]]
    assert rec.end is None  # the RunEnd came after the disk was full: not claimed
