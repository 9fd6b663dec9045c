"""Turn SIGTERM/SIGINT into an orderly exit so `with Bus(...)` closes Zenoh before exiting."""

from __future__ import annotations

import signal
from types import FrameType


class Shutdown(BaseException):
    """Raised in the main thread when the process is asked to stop.

    A BaseException, like KeyboardInterrupt: a signal can land while any code runs, and an
    `except Exception` on the way (a decoder turning every error into its own) must not
    swallow the request to stop. Seen: the SIGTERM exit test hung 3 times in 24 while it
    was an Exception.
    """


def install_shutdown_handlers() -> None:
    """SIGTERM and SIGINT raise Shutdown in the main thread (once; a second one kills)."""

    def handler(signum: int, frame: FrameType | None) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        raise Shutdown(signal.Signals(signum).name)

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
