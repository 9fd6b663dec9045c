"""SIGTERM/SIGINT as an orderly stop, two ways.

A service process turns them into a `Shutdown` raised in its main thread, so `with Bus(...)`
closes Zenoh before it exits; a driver of a run (lockstep coordinator, realtime driver,
launcher) turns them into flags its loop polls (`stop_on_signals`), so stopping its children
is never cut short half-way.
"""

from __future__ import annotations

import os
import select
import signal
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from types import FrameType
from typing import Any


class Shutdown(BaseException):
    """Raised in the main thread when the process is asked to stop.

    A BaseException, like KeyboardInterrupt: a signal can land while any code runs, and an
    `except Exception` on the way (a decoder turning every error into its own) must not
    swallow the request to stop. Seen: the SIGTERM exit test hung 3 times in 24 while it
    was an Exception.
    """


# How long an orderly stop may take before the kernel ends the process (SIGALRM's default
# action): a stop that hangs (a Zenoh close with its router gone, a callback thread never
# undeclared) must not leave the process behind when nobody will send a second signal, as
# when the kernel's parent-death signal is the only one it gets (seen in CI: a service that
# outlived its SIGKILLed launcher).
STOP_DEADLINE_S = 5.0


def install_shutdown_handlers() -> None:
    """SIGTERM and SIGINT raise Shutdown in the main thread (once; a second one kills, and so
    does an orderly stop still running STOP_DEADLINE_S later)."""

    def handler(signum: int, frame: FrameType | None) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        signal.signal(signal.SIGINT, signal.SIG_DFL)
        signal.signal(signal.SIGALRM, signal.SIG_DFL)
        signal.setitimer(signal.ITIMER_REAL, STOP_DEADLINE_S)
        raise Shutdown(signal.Signals(signum).name)

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)


def wait_for_stop() -> None:
    """Block the main thread until SIGTERM or SIGINT raises Shutdown in it.

    Not `signal.pause()`: the kernel delivers a process-wide signal (the parent-death one
    included) to any thread that does not block it, often one of Zenoh's, and pause() in the
    main thread then never returns; Python only runs the handler when the main thread runs.
    CPython's C-level handler writes to the wakeup fd in whichever thread it runs, so a
    select on it wakes the main thread, which then runs the handler (seen in CI: a router
    that outlived its SIGKILLed launcher).
    """
    r, w = os.pipe()
    os.set_blocking(w, False)
    previous = signal.set_wakeup_fd(w, warn_on_full_buffer=False)
    try:
        while True:
            select.select([r], [], [])
            os.read(r, 64)  # the handler runs before the next bytecode: Shutdown propagates
    finally:
        signal.set_wakeup_fd(previous)
        os.close(r)
        os.close(w)


class Interrupted(Exception):
    """The launch was asked to stop (Ctrl-C or SIGTERM) before the mission ended."""


class StopRequest:
    """Counts stop signals: the first asks for an orderly stop, a second one to hurry."""

    def __init__(self) -> None:
        self.count = 0
        self.signal_name = ""

    @property
    def requested(self) -> bool:
        return self.count > 0

    @property
    def hurry(self) -> bool:
        return self.count > 1

    def _on_signal(self, signum: int, frame: FrameType | None) -> None:
        self.count += 1
        self.signal_name = signal.Signals(signum).name

    def check(self) -> None:
        """Raise Interrupted if a stop was asked for."""
        if self.requested:
            raise Interrupted(self.signal_name)


@contextmanager
def stop_on_signals() -> Iterator[StopRequest]:
    """Within the block SIGINT and SIGTERM only set flags (no KeyboardInterrupt half-way
    through stopping the children); the previous handlers come back afterwards."""
    stop = StopRequest()
    if threading.current_thread() is not threading.main_thread():
        yield stop  # signal handlers can only be set from the main thread
        return
    previous: dict[signal.Signals, Any] = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        previous[sig] = signal.signal(sig, stop._on_signal)
    try:
        yield stop
    finally:
        for old, handler in previous.items():
            signal.signal(old, handler)
