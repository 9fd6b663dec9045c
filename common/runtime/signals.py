"""Turn SIGTERM/SIGINT into an orderly exit so `with Bus(...)` closes Zenoh before exiting."""

from __future__ import annotations

import signal
from types import FrameType


class Shutdown(Exception):
    """Raised in the main thread when the process is asked to stop."""


def install_shutdown_handlers() -> None:
    """SIGTERM and SIGINT raise Shutdown in the main thread (once; a second one kills)."""

    def handler(signum: int, frame: FrameType | None) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        raise Shutdown(signal.Signals(signum).name)

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
