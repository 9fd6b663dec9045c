"""RunWriter: one run's frames, routing, liveliness and Foxglove view, written to MCAP.

The file is chunked (CHUNK_BYTES, compressed with zstd or lz4 when importable) and flushed
every FLUSH_EVERY_S at most: a recorder killed with SIGKILL leaves a file whose every chunk
written so far reads back (services/recording/reader.py says how much was lost). The
metadata goes first and is flushed at once, so even a file cut short says what run it is.
The layout is described in services/recording/layout.py.

A disk that fills (or any write error) ends the recording, not the run: the file is cut back
to its last whole chunk and closed there with MCAP's end records (a data end and a footer
without a summary), so it reads to that point as a complete file; `failed` keeps the error,
and what comes later is counted in `lost`, not written.
"""

from __future__ import annotations

import json
import logging
import os
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from mcap.data_stream import RecordBuilder
from mcap.records import DataEnd, Footer
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer

from common.jsonsafe import JsonObject
from common.messages import WIRE_VERSION, Message, WireError, decode
from common.view import View, ViewMessage
from services.recording import layout

log = logging.getLogger("tidelink.recording")

CHUNK_BYTES = 64 * 1024  # small chunks: a killed recorder loses at most one
FLUSH_EVERY_S = 0.5  # and at most this much of the run


def _compression() -> CompressionType:
    """zstd, else lz4, else none: whichever this Python can write (the mcap package's
    optional dependencies)."""
    try:
        import zstandard  # noqa: F401

        return CompressionType.ZSTD
    except ImportError:
        pass
    try:
        import lz4.frame  # noqa: F401

        return CompressionType.LZ4
    except ImportError:
        return CompressionType.NONE


@dataclass(frozen=True, kw_only=True)
class RunInfo:
    """What a recording says about itself (its `tidelink` metadata record)."""

    run: str
    vehicle: str
    scenario_raw: JsonObject
    recorder: str  # "launch" (in-process, lossless) or "record" (remote, through a watcher)

    def metadata(self) -> dict[str, str]:
        return {
            "format": str(layout.FORMAT_VERSION),
            "wire_version": str(WIRE_VERSION),
            "run": self.run,
            "vehicle": self.vehicle,
            "recorder": self.recorder,
            "scenario": json.dumps(self.scenario_raw, sort_keys=True),
        }


def _ns(wall: float) -> int:
    return round(wall * 1e9)


_os_write = os.write  # the sink's one write call (a seam: tests fill the disk through it)


class _Sink:
    """The stream the MCAP writer writes to: buffered here, written to the file on `flush`
    (the writer's, after a whole chunk), remembering the end of the last whole write. A write
    that fails (ENOSPC) cuts the file back there and closes it with MCAP's end records."""

    def __init__(self, path: Path) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._buf = bytearray()
        self._pos = 0  # bytes on disk
        self.failed: OSError | None = None

    def write(self, data: bytes) -> int:
        if self.failed is None:
            self._buf += data
        return len(data)

    def tell(self) -> int:
        return self._pos + len(self._buf)

    def flush(self) -> None:
        if self.failed is not None or not self._buf:
            return
        done = 0
        try:
            with memoryview(self._buf) as view:
                while done < len(view):
                    done += _os_write(self._fd, view[done:])
        except OSError as exc:
            self._cut(exc)
            raise
        self._pos += len(self._buf)
        self._buf.clear()

    def _cut(self, exc: OSError) -> None:
        """Back to the end of the last whole write, then MCAP's end records there."""
        self.failed = exc
        self._buf = bytearray()  # a new one: a view of the old may live on in the traceback
        end = RecordBuilder()
        DataEnd(0).write(end)
        Footer(summary_start=0, summary_offset_start=0, summary_crc=0).write(end)
        try:
            os.ftruncate(self._fd, self._pos)
            os.pwrite(self._fd, end.end() + MCAP0_MAGIC, self._pos)
        except OSError as again:  # no room even for that: the file reads to its last chunk
            log.warning("could not close the recording at its last whole chunk: %s", again)

    def close(self) -> None:
        if self._fd >= 0:
            os.close(self._fd)
            self._fd = -1


class RunWriter:
    """Writes one run to an MCAP file; `close` finishes it (summary, indexes, footer)."""

    def __init__(
        self,
        path: Path,
        info: RunInfo,
        types: layout.StreamTypes,
        *,
        view: View | None = None,
        flush_every_s: float = FLUSH_EVERY_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._types = types
        self._view = view
        self._flush_every_s = flush_every_s
        self._clock = clock
        self._fh = _Sink(path)  # closed in close()
        self._w = Writer(self._fh, chunk_size=CHUNK_BYTES, compression=_compression())  # type: ignore[arg-type]
        self._w.start(profile=layout.PROFILE, library=f"tidelink (wire {WIRE_VERSION})")
        self._w.add_metadata(layout.METADATA, info.metadata())
        self._schemas: dict[tuple[str, str, bytes], int] = {}
        self._channels: dict[str, int] = {}
        self.counts: Counter[str] = Counter()  # frames per "service/stream" in the file
        self._pending: Counter[str] = Counter()  # ... handed over since the last flush
        self.lost = 0  # frames not in the file because writing it failed (see `failed`)
        self.undecodable = 0  # frames that are no tidelink message (kept, with no schema)
        self.view_errors = 0
        self._closed = False
        if view is not None:
            for vm in view.static():
                self._view_message(vm, time.time())
        self._flush(self._w.flush)
        self._next_flush = clock() + flush_every_s

    # -- channels ------------------------------------------------------------------------------
    def _schema(self, name: str, encoding: str, data: bytes) -> int:
        key = (name, encoding, data)
        sid = self._schemas.get(key)
        if sid is None:
            sid = self._schemas[key] = self._w.register_schema(name, encoding, data)
        return sid

    def _channel(self, topic: str, encoding: str, schema_id: int, meta: dict[str, str]) -> int:
        cid = self._channels.get(topic)
        if cid is None:
            cid = self._channels[topic] = self._w.register_channel(topic, encoding, schema_id, meta)
        return cid

    def _frame_channel(self, service: str, stream: str, msg: Message | None) -> int:
        topic = layout.frame_topic(service, stream)
        cid = self._channels.get(topic)
        if cid is not None:
            return cid
        # the declared type; a stream the dataflow does not declare: its first message's
        cls = self._types.get((service, stream)) or (type(msg) if msg is not None else None)
        sid = 0
        if cls is not None:
            name, schema = layout.frame_schema(cls)
            sid = self._schema(name, "jsonschema", schema)
        meta = {layout.KIND: layout.FRAME, "service": service, "stream": stream}
        return self._channel(topic, layout.RAW_ENCODING, sid, meta)

    # -- content -------------------------------------------------------------------------------
    def frame(
        self, service: str, stream: str, payload: bytes, attachment: bytes | None, wall: float
    ) -> Message | None:
        """Write one frame as it crossed the wire (and its attachment, and its view); returns
        the decoded message, or None if it is none (still written, byte for byte)."""
        try:
            msg: Message | None = decode(payload)
        except WireError:
            msg = None
            self.undecodable += 1
        if self.failed is not None:
            self.lost += 1
            return msg
        cid = self._frame_channel(service, stream, msg)
        t = _ns(wall)
        seq = (msg.seq if msg is not None else 0) & 0xFFFFFFFF
        self._w.add_message(cid, log_time=t, data=payload, publish_time=t, sequence=seq)
        if attachment is not None:
            rid = self._channel(
                layout.routing_topic(service, stream),
                layout.RAW_ENCODING,
                self._schema(layout.ROUTING_SCHEMA_NAME, "jsonschema", layout.ROUTING_SCHEMA),
                {layout.KIND: layout.ROUTING, "service": service, "stream": stream},
            )
            self._w.add_message(rid, log_time=t, data=attachment, publish_time=t, sequence=seq)
        self._pending[layout.stream_name(service, stream)] += 1
        if msg is not None and self._view is not None:
            try:
                for vm in self._view.translate(service, stream, msg):
                    self._view_message(vm, wall)
            except Exception as exc:  # noqa: BLE001 - a view bug must not lose the raw run
                self.view_errors += 1
                if self.view_errors == 1:
                    log.warning("Foxglove view of %s/%s failed: %s", service, stream, exc)
        return msg

    def alive(self, service: str, alive: bool, wall: float) -> None:
        """Write a liveliness change of `service`."""
        if self.failed is not None:
            return
        cid = self._channel(
            layout.ALIVE_TOPIC,
            "json",
            self._schema(layout.ALIVE_SCHEMA_NAME, "jsonschema", layout.ALIVE_SCHEMA),
            {layout.KIND: layout.ALIVE},
        )
        data = json.dumps({"service": service, "alive": alive}).encode()
        t = _ns(wall)
        self._w.add_message(cid, log_time=t, data=data, publish_time=t)

    def _view_message(self, vm: ViewMessage, wall: float) -> None:
        sid = self._schema(vm.schema_name, vm.schema_encoding, vm.schema) if vm.schema_name else 0
        cid = self._channel(vm.topic, vm.message_encoding, sid, {layout.KIND: layout.VIEW})
        t = _ns(wall)
        self._w.add_message(cid, log_time=t, data=vm.data, publish_time=t)

    # -- on disk -------------------------------------------------------------------------------
    def flush_if_due(self) -> None:
        """Write the chunk in progress if FLUSH_EVERY_S has passed since the last flush."""
        now = self._clock()
        if now >= self._next_flush:
            self._flush(self._w.flush)
            self._next_flush = now + self._flush_every_s

    def _flush(self, write: Callable[[], None]) -> None:
        """`write` (the MCAP writer's flush or finish) through to the file; a write error is
        kept in `failed` (the file is then closed at its last whole chunk), never raised."""
        if self.failed is not None:
            return
        try:
            write()
            self._fh.flush()
        except OSError as exc:
            self.lost += sum(self._pending.values())
            self._pending.clear()
            if self._fh.failed is None:
                self._fh.failed = exc
            log.error("recording stopped: %s (the file ends at its last whole chunk)", exc)
            return
        self.counts.update(self._pending)
        self._pending.clear()

    @property
    def failed(self) -> OSError | None:
        """The write error that ended the recording, if one did."""
        return self._fh.failed

    @property
    def frames(self) -> int:
        return sum(self.counts.values())

    def close(self) -> None:
        """Finish the file (summary, indexes, footer) and close it; idempotent. After a write
        error the file is already closed at its last whole chunk."""
        if self._closed:
            return
        self._closed = True
        try:
            self._flush(self._w.finish)
        finally:
            self._fh.close()
