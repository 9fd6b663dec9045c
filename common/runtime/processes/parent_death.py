"""A child process that dies with its parent, however the parent dies (Linux's PDEATHSIG)."""

from __future__ import annotations

import ctypes
import os
import signal
import sys
from collections.abc import Callable

# Linux's prctl, looked up once at import: a child between fork and exec must not load anything
_PRCTL: Callable[..., int] | None = None
if sys.platform.startswith("linux"):
    _PRCTL = ctypes.CDLL(None, use_errno=True).prctl
PR_SET_PDEATHSIG = 1


def die_with(parent: int) -> Callable[[], None]:
    """What a child runs first: SIGTERM it when its parent `parent` dies, however it dies (a
    SIGKILLed launcher left its router listening for good). SIGTERM, not SIGKILL: the child
    still closes its Zenoh session and its own children in order. Linux ties this to the
    thread that started the child: ours start from the thread that supervises them, or from
    the fork server's only thread."""

    def arm() -> None:
        if _PRCTL is not None:
            _PRCTL(PR_SET_PDEATHSIG, signal.SIGTERM)
            if os.getppid() != parent:  # the parent died before the line above
                os._exit(1)

    return arm
