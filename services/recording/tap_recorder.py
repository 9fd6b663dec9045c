"""TapRecorder: a run recorded in its clock's own process, from the watch tap, losslessly.

`tidelink launch --record` attaches one to the clock side before any service starts. The tap
hands it every frame on Zenoh's thread, where it only enqueues; a writer thread drains the
queue into a RunWriter. Nothing is published, so nothing is dropped: the recording holds
every frame the run's driver recorded, and the RunEnd.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from pathlib import Path
from types import TracebackType
from typing import Any

from common.bus import Liveliness
from common.bus.keys import Keys
from common.bus.watcher import WatchedFrame
from common.config.scenario import scenario_from_raw
from common.jsonsafe import JsonObject
from common.runtime.distributed.bringup import ClockSide
from common.view import View
from services.recording.layout import stream_types
from services.recording.writer import FLUSH_EVERY_S, RunInfo, RunWriter

log = logging.getLogger("tidelink.recording")

_STOP = object()  # queued by close: the writer thread drains up to it and returns


class TapRecorder:
    """Records the run of `side` to `path`; use as a context manager around the run."""

    def __init__(
        self, side: ClockSide, path: Path, scenario_raw: JsonObject, view: View | None = None
    ) -> None:
        self.side = side
        self.path = path
        keys: Keys = side.tap.keys
        scenario = scenario_from_raw(scenario_raw)
        info = RunInfo(
            run=keys.run, vehicle=keys.vehicle, scenario_raw=scenario_raw, recorder="launch"
        )
        self.writer = RunWriter(path, info, stream_types(scenario), view=view)
        self._q: queue.SimpleQueue[Any] = queue.SimpleQueue()
        self._thread = threading.Thread(target=self._drain, name="tidelink-recorder", daemon=True)
        self.error: BaseException | None = None

    def __enter__(self) -> TapRecorder:
        self._thread.start()
        self.side.tap.add_sink(self._q.put)  # a C call on Zenoh's thread: nothing else
        self.side.bus.on_alive(self.side.tap.keys.all_alive, self._on_alive)
        return self

    def _on_alive(self, ev: Liveliness) -> None:
        self._q.put((time.time(), ev))  # stamped on arrival: the writer may be behind

    def _drain(self) -> None:
        w = self.writer
        while True:
            try:
                item = self._q.get(timeout=FLUSH_EVERY_S)
            except queue.Empty:
                item = None
            try:
                if item is _STOP:
                    return
                if isinstance(item, WatchedFrame):
                    w.frame(item.service, item.stream, item.payload, item.attachment, item.wall)
                elif item is not None:
                    wall, ev = item
                    w.alive(Keys.parse_alive(ev.key)[2], ev.alive, wall)
                w.flush_if_due()
            except Exception as exc:  # noqa: BLE001 - a failing disk must not stop the run
                self._failed(exc)

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()

    def close(self) -> None:
        """Write what is queued, then finish the file (a failure is kept in `error`, never
        raised: the run's own outputs come first)."""
        self._q.put(_STOP)
        self._thread.join()
        try:
            self.writer.close()
        except Exception as exc:  # noqa: BLE001 - see the docstring
            self._failed(exc)
        if self.writer.failed is not None:  # a full disk: the file ends at its last chunk
            self._failed(self.writer.failed)

    def _failed(self, exc: BaseException) -> None:
        if self.error is None:
            self.error = exc
            log.error("recording to %s failed: %s (the run goes on)", self.path, exc)
