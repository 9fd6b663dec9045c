"""The lockstep mission loop of a launch: the runtime's Coordinator, fed by the launcher.

The coordinator's tick protocol is used unchanged; only the bring-up differs (a separate
router process, services started by the supervisor or joining from other hosts), and the
launcher watches the record for its progress display and for Ctrl-C. Restarts make no sense
here (a restarted service loses its state and the run its determinism): any exit fails it.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

from common.bus import Inbox, Received
from common.config.scenario import Scenario
from common.messages import Tick, TickAck
from common.runtime.lockstep import Coordinator
from services.launcher.interrupt import StopRequest
from services.launcher.progress import Display, MissionView

SHOW_EVERY_S = 0.25


class LockstepDriver(Coordinator):
    """A Coordinator that reports progress and stops on request (raises Interrupted)."""

    def __init__(
        self,
        scenario: Scenario,
        raw: dict[str, Any],
        log_dir: Path,
        view: MissionView,
        display: Display,
        stop: StopRequest,
    ) -> None:
        super().__init__(scenario, raw, log_dir)
        self.view = view
        self.display = display
        self.stop = stop
        self._next_show = 0.0

    def await_alive(self, inbox: Inbox) -> None:
        t0 = time.monotonic()
        self._await_alive(inbox)
        self.display.event(
            f"all {len(self.mission.names)} services alive after {time.monotonic() - t0:.2f} s"
        )

    def _pump(self, inbox: Inbox, deadline: float, what: str) -> None:
        self.stop.check()
        super()._pump(inbox, deadline, what)
        now = time.monotonic()
        if now >= self._next_show:
            self._next_show = now + SHOW_EVERY_S
            self.display.update(self.view, self.view.t_sim)

    def _on_message(self, ev: Received) -> None:
        super()._on_message(ev)
        if isinstance(ev.msg, Tick | TickAck):
            return
        try:
            service, stream = self.keys.split(ev.key)
        except ValueError:
            return
        line = self.view.see(service, stream, ev.msg)
        if line:
            self.display.event(line)
