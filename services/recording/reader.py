"""Reading a recording back: its metadata, frames and liveliness, with errors naming the file.

A file cut short (a recorder that was killed) is read up to its last whole chunk, and the
Recording says how much was lost; anything that is not a tidelink recording, or one in a
wire version this build cannot decode, raises RecordingError naming the file.
"""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any

from mcap.records import Channel, Chunk, Footer, Message, Metadata
from mcap.stream_reader import StreamReader, breakup_chunk

from common.bus import CLOCK
from common.bus.keys import END
from common.jsonsafe import JsonObject
from common.messages import WIRE_VERSION, RunEnd, WireError, decode
from services.recording import layout

log = logging.getLogger("tidelink.recording")

MAGIC = b"\x89MCAP0\r\n"


class RecordingError(ValueError):
    """The file is no readable tidelink recording (the message names the file)."""


@dataclass(frozen=True)
class RecordedFrame:
    """A frame as recorded: its stream, the bytes that crossed the wire, and when the run's
    watch tap got it (Unix seconds)."""

    service: str
    stream: str
    payload: bytes
    attachment: bytes | None
    wall: float


@dataclass(frozen=True)
class AliveEvent:
    """A service's liveliness token appeared (alive) or vanished, as the recorder saw it."""

    service: str
    alive: bool
    wall: float


RecordedEvent = RecordedFrame | AliveEvent


@dataclass(frozen=True)
class Truncation:
    """A file that ends before MCAP's footer: how much of it was read."""

    read_bytes: int
    size_bytes: int
    why: str

    def describe(self, path: Path) -> str:
        lost = self.size_bytes - self.read_bytes
        if lost == 0:
            return (
                f"{path}: not closed (no MCAP footer: the recorder was killed?); "
                f"all {self.size_bytes} bytes read"
            )
        return (
            f"{path}: truncated: read {self.read_bytes} of {self.size_bytes} bytes; the last "
            f"{lost} bytes (an unfinished chunk: the recorder was killed?) are lost ({self.why})"
        )


@dataclass(frozen=True)
class Recording:
    """A recorded run: what it was (metadata), what happened, in the order recorded."""

    path: Path
    run: str
    vehicle: str
    recorder: str
    scenario_raw: JsonObject
    events: tuple[RecordedEvent, ...]
    truncation: Truncation | None

    @property
    def frames(self) -> list[RecordedFrame]:
        return [e for e in self.events if isinstance(e, RecordedFrame)]

    @property
    def end(self) -> RunEnd | None:
        """The run's RunEnd (None if the recording stops before it)."""
        for e in reversed(self.events):
            if isinstance(e, RecordedFrame) and (e.service, e.stream) == (CLOCK, END):
                try:
                    msg = decode(e.payload)
                except WireError as exc:
                    raise RecordingError(
                        f"{self.path}: its RunEnd frame is invalid: {exc}"
                    ) from None
                if isinstance(msg, RunEnd):
                    return msg
        return None


def read_recording(path: Path) -> Recording:
    """Read a recording (see the module docstring); RecordingError naming `path` if it is not
    one, and a logged warning if it is cut short."""
    try:
        fh = open(path, "rb")  # noqa: SIM115 - closed below
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read it: {exc.strerror}") from None
    with fh:
        head = fh.read(len(MAGIC))
        if head != MAGIC:
            what = "it is empty" if not head else "it does not start with MCAP's magic bytes"
            raise RecordingError(f"{path}: not an MCAP file ({what})")
        fh.seek(0)
        rec = _Parser(path).parse(fh)
    if rec.truncation is not None:
        log.warning("%s", rec.truncation.describe(path))
    return rec


class _Parser:
    """Walks the file's records in order, up to the end or the first unreadable byte."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.meta: dict[str, str] | None = None
        self.channels: dict[int, Channel] = {}
        self.events: list[RecordedEvent] = []
        self.last_frame: dict[tuple[str, str], int] = {}  # stream -> index in events
        self.unpaired = 0

    def parse(self, fh: IO[bytes]) -> Recording:
        size = fh.seek(0, 2)
        fh.seek(0)
        records = StreamReader(fh, emit_chunks=True, validate_crcs=True).records
        good = 0
        truncation = None
        while True:
            try:
                record = next(records)
                inner = (
                    breakup_chunk(record, validate_crc=True)
                    if isinstance(record, Chunk)
                    else [record]
                )
            except StopIteration:
                break
            except Exception as exc:  # noqa: BLE001 - whatever fails to parse is where it ends
                truncation = Truncation(good, size, f"{type(exc).__name__}: {exc}".rstrip(": "))
                break
            for r in inner:
                self._take(r)
            good = fh.tell()
            if isinstance(record, Footer):
                break
        if self.meta is None:
            if truncation is not None:
                raise RecordingError(
                    f"{self.path}: cut short before its tidelink metadata "
                    f"(read {good} of {size} bytes)"
                )
            raise RecordingError(
                f"{self.path}: an MCAP file, but not a tidelink recording "
                f"(no '{layout.METADATA}' metadata)"
            )
        if self.unpaired:
            log.warning("%s: %d routing attachments without their frame", self.path, self.unpaired)
        return Recording(
            path=self.path,
            run=self.meta["run"],
            vehicle=self.meta["vehicle"],
            recorder=self.meta.get("recorder", ""),
            scenario_raw=self._scenario(self.meta),
            events=tuple(self.events),
            truncation=truncation,
        )

    def _take(self, r: Any) -> None:
        if isinstance(r, Metadata) and r.name == layout.METADATA:
            self._metadata(r.metadata)
        elif isinstance(r, Channel):
            self.channels.setdefault(r.id, r)  # the summary repeats them
        elif isinstance(r, Message):
            ch = self.channels.get(r.channel_id)
            if ch is None:
                raise RecordingError(
                    f"{self.path}: a message on channel {r.channel_id}, never declared"
                )
            self._message(ch, r)

    def _metadata(self, meta: dict[str, str]) -> None:
        missing = [k for k in ("wire_version", "run", "vehicle", "scenario") if k not in meta]
        if missing:
            raise RecordingError(f"{self.path}: its tidelink metadata lacks {', '.join(missing)}")
        try:
            version = int(meta["wire_version"])
        except ValueError:
            raise RecordingError(
                f"{self.path}: wire_version {meta['wire_version']!r} is not a number"
            ) from None
        if version > WIRE_VERSION:
            raise RecordingError(
                f"{self.path}: recorded with wire version {version}, newer than this build's "
                f"{WIRE_VERSION}; read it with a newer tidelink"
            )
        if version < WIRE_VERSION:
            raise RecordingError(
                f"{self.path}: recorded with wire version {version}; this build decodes only "
                f"version {WIRE_VERSION}"
            )
        self.meta = meta

    def _scenario(self, meta: dict[str, str]) -> JsonObject:
        try:
            raw = json.loads(meta["scenario"])
        except ValueError as exc:
            raise RecordingError(f"{self.path}: its scenario metadata is not JSON: {exc}") from None
        if not isinstance(raw, dict):
            raise RecordingError(f"{self.path}: its scenario metadata is not a JSON object")
        return raw

    def _message(self, ch: Channel, r: Message) -> None:
        kind = ch.metadata.get(layout.KIND)
        wall = r.log_time / 1e9
        if kind == layout.FRAME:
            stream = (ch.metadata["service"], ch.metadata["stream"])
            self.last_frame[stream] = len(self.events)
            self.events.append(RecordedFrame(*stream, r.data, None, wall))
        elif kind == layout.ROUTING:
            # written right after its frame: pair it with the stream's newest frame
            i = self.last_frame.get((ch.metadata["service"], ch.metadata["stream"]))
            f = self.events[i] if i is not None else None
            if isinstance(f, RecordedFrame) and f.attachment is None and f.wall == wall:
                self.events[i] = replace(f, attachment=r.data)  # type: ignore[index]
            else:
                self.unpaired += 1
        elif kind == layout.ALIVE:
            try:
                data = json.loads(r.data)
                self.events.append(AliveEvent(str(data["service"]), bool(data["alive"]), wall))
            except (ValueError, KeyError, TypeError) as exc:
                raise RecordingError(f"{self.path}: a bad liveliness record: {exc}") from None
