"""The realtime runtime: one OS process per service over Zenoh on the (scaled) wall clock."""

from __future__ import annotations

import logging
import tempfile
import time
from pathlib import Path
from typing import Any

from common.bus import Inbox
from common.config.scenario import Scenario
from common.messages import Tick
from common.runtime.inproc import RunResult
from common.runtime.lockstep import Coordinator
from common.runtime.ticks import TickSender

log = logging.getLogger("tidelink.realtime")


class RealtimeSupervisor(Coordinator):
    """Starts the services, starts the mission clock, records until the mission ends."""

    service_module = "common.runtime.realtime_service"

    def drive(self, inbox: Inbox, pub: TickSender) -> RunResult:
        scale = self.scenario.runtime.time_scale
        pub.put(Tick(stamp=0.0, tick=0, time_us=0, watermarks={}))
        t0 = time.monotonic()
        reason = "max_time"
        while True:
            t_virtual = (time.monotonic() - t0) * scale
            if t_virtual >= self.mission.max_time_s:
                break
            end = self.mission.observe(self.record)
            if end is not None:
                reason = end
                break
            self._pump(inbox, time.monotonic() + self.timeout_s, "data")
        t_end = (time.monotonic() - t0) * scale
        pub.put(Tick(stamp=t_end, tick=1, time_us=round(t_end * 1e6), watermarks={}, stop=True))
        # collect the final statistics each service sends as it stops
        deadline = time.monotonic() + 5.0
        self.stopping = True
        while time.monotonic() < deadline and any(
            self.record.last_seq(n, "stats") == 0 or c.proc.poll() is None
            for n, c in self.children.items()
        ):
            self.finished.update(n for n, c in self.children.items() if c.proc.poll() is not None)
            self.finished.update(self.children)  # exits are expected from now on
            self._pump(inbox, deadline + 1.0, "final statistics")
        log.info("realtime run ended at t=%.3f s (x%.1f): %s", t_end, scale, reason)
        return RunResult(reason, t_end, 0, self.record, self.mission.metrics(self.record))


def run_realtime(scenario: Scenario, raw: dict[str, Any], log_dir: Path | None = None) -> RunResult:
    """Run a mission in real time (scaled by runtime.time_scale) across service processes."""
    if log_dir is None:
        log_dir = Path(tempfile.mkdtemp(prefix="tidelink-logs-"))
    return RealtimeSupervisor(scenario, raw, log_dir).run()
