"""Hooks a run's driver calls as the run goes (progress, logs): passed in, not overridden."""

from __future__ import annotations

import logging
from typing import Protocol

from common.messages import Message

log = logging.getLogger("tidelink.run")


class RunObserver(Protocol):
    """What a driver (lockstep coordinator, realtime driver) tells whoever watches the run."""

    def event(self, text: str) -> None:
        """Something worth a line: services up, clock started, a service gone, the end."""

    def message(self, service: str, stream: str, msg: Message) -> None:
        """Every message recorded, as it is recorded."""

    def progress(self, t_s: float) -> None:
        """The mission time now (called a few times a second at most)."""


class LogObserver:
    """The default observer: events go to the log; messages and progress are not shown."""

    def event(self, text: str) -> None:
        log.info("%s", text)

    def message(self, service: str, stream: str, msg: Message) -> None:
        return None

    def progress(self, t_s: float) -> None:
        return None
