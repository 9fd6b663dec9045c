"""Service processes forked from a pre-imported server, instead of a fresh interpreter each.

A service process spends over a second of CPU importing numpy, scipy and filterpy before it
does anything; with four services on two cores that was most of a lockstep run's start-up
(docs/notes/0001-fork-server-for-services.md). Here a
multiprocessing fork server imports the service modules once, and every service process is
forked from it: a copy of that memory, ready in milliseconds. The server is a fresh Python
that never opens a Zenoh session, so no Zenoh thread or runtime is ever forked (forking a
process that has one would leave the child a runtime without threads).

The child is still a separate OS process with its own Zenoh session, its own log file, its
own exit code: exactly what `python -m module args` would have been.
"""

from __future__ import annotations

import contextlib
import importlib
import multiprocessing
import os
import subprocess
import sys
import tempfile
import types
from collections.abc import Iterator
from multiprocessing.process import BaseProcess
from pathlib import Path

from common.runtime.processes.parent_death import die_with

# What the fork server imports once (its children find them already loaded). A mission
# module not listed here is imported by each child, which is slower but just as correct.
RUNTIMES = (
    "common.runtime.distributed.lockstep_service",
    "common.runtime.distributed.realtime_service",
)
PRELOAD = (
    *RUNTIMES,
    "services.mission.auv",
    # each service's core (the mission's factories import them lazily, see its dataflow)
    "services.estimator.core",
    "services.planner.core",
    "services.sensor.core",
    "services.tracker.core",
    "services.vehicle.core",
)


def _context(preload: tuple[str, ...] = PRELOAD) -> multiprocessing.context.ForkServerContext:
    ctx = multiprocessing.get_context("forkserver")
    ctx.set_forkserver_preload(list(preload))  # no effect once the server runs: fine
    return ctx


def warm_up(preload: tuple[str, ...] = PRELOAD) -> None:
    """Start the fork server now (it imports `preload`), so the first service starts at once.
    A process that runs one mission (a launch) may name only what that mission's services
    import; one that runs many keeps the default, the AUV mission's services."""
    _context(preload)
    from multiprocessing import forkserver

    with _short_tempdir():
        forkserver.ensure_running()


def _child(
    module: str, argv: list[str], log_path: str, env: dict[str, str], append: bool, group: bool
) -> None:
    """Runs in the forked process: die with the fork server (which dies with the process that
    started it), lead a process group of its own if `group`, log to the file, then
    `module.main(argv)`, exit with it."""
    _let_the_server_go()
    die_with(os.getppid())()
    if group:
        os.setsid()  # a terminal's Ctrl-C reaches its supervisor, which stops it in order
    keep = os.O_APPEND if append else os.O_TRUNC
    fd = os.open(log_path, os.O_WRONLY | os.O_CREAT | keep, 0o644)
    os.dup2(fd, 1)
    os.dup2(fd, 2)
    os.close(fd)
    null = os.open(os.devnull, os.O_RDONLY)
    os.dup2(null, 0)
    os.close(null)
    sys.stdout.reconfigure(line_buffering=True)  # type: ignore[union-attr]
    os.environ.update(env)
    code = importlib.import_module(module).main(argv)
    sys.stdout.flush()
    sys.exit(code)


def _let_the_server_go() -> None:
    """Close this child's copy of the write end of the fork server's "alive" pipe.

    multiprocessing hands it to every child it forks (so that the child could fork through
    the same server); the server exits when the pipe's last writer is gone. While a child
    held it, the server outlived the process that started it (a SIGKILLed launcher), and so
    did its children, whose parent-death signal waits for the server: they lingered until
    their own timeouts (30 s). Our children never fork through it."""
    from multiprocessing import forkserver

    server = getattr(forkserver, "_forkserver", None)
    fd = getattr(server, "_forkserver_alive_fd", None)
    if fd is not None:
        os.close(fd)
        server._forkserver_alive_fd = None  # type: ignore[union-attr]


class ForkedProcess:
    """A forked service process with the part of subprocess.Popen's interface we use."""

    def __init__(self, proc: BaseProcess, args: list[str]) -> None:
        self._proc = proc
        self.args = args
        pid = proc.pid
        assert pid is not None, "started processes have a pid"
        self.pid: int = pid

    @property
    def returncode(self) -> int | None:
        """The exit code; -N when a signal N ended it; None while it runs."""
        return self._proc.exitcode

    def poll(self) -> int | None:
        return self._proc.exitcode

    def wait(self, timeout: float | None = None) -> int:
        """Wait for the exit (on the process's sentinel, no polling); TimeoutExpired if not."""
        self._proc.join(timeout)
        code = self._proc.exitcode
        if code is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return code

    def send_signal(self, sig: int) -> None:
        with contextlib.suppress(ProcessLookupError):
            os.kill(self.pid, sig)


def fork_module(
    module: str,
    argv: list[str],
    log_path: Path,
    env: dict[str, str] | None = None,
    *,
    append: bool = False,
    group: bool = False,
) -> ForkedProcess:
    """Start `module.main(argv)` in a process forked from the fork server, logging to a file;
    `group`: leading a process group (a session) of its own, as children.spawn's."""
    proc = _context().Process(
        target=_child,
        args=(module, argv, str(log_path), dict(env or {}), append, group),
        name=f"tidelink:{module}",
        daemon=True,  # multiprocessing terminates any left at our exit: none is orphaned
    )
    with _main_module_hidden(), _short_tempdir():
        proc.start()
    return ForkedProcess(proc, [module, *argv])


# the fork server listens on an AF_UNIX socket in multiprocessing's pymp-* folder under the
# temp dir (made once per process); a socket path holds at most 107 bytes, which a long
# TMPDIR leaves too little of ("AF_UNIX path too long")
_SOCKET_TEMPDIR_MAX = 60


@contextlib.contextmanager
def _short_tempdir() -> Iterator[None]:
    """Within: a temp dir short enough for the fork server's socket (/tmp if it is not)."""
    if len(tempfile.gettempdir()) <= _SOCKET_TEMPDIR_MAX:
        yield
        return
    saved = tempfile.tempdir
    tempfile.tempdir = "/tmp"
    try:
        yield
    finally:
        tempfile.tempdir = saved


@contextlib.contextmanager
def _main_module_hidden() -> Iterator[None]:
    """Start children without multiprocessing's re-import of our __main__ in them.

    multiprocessing re-runs the parent's main script in each child (as __mp_main__), which
    breaks any script that calls a lockstep run without an `if __name__ == "__main__":`
    guard, and costs time in every other. Our children need nothing from it (their target
    lives in this module), so while a child starts, __main__ is a blank module.
    """
    real = sys.modules["__main__"]
    sys.modules["__main__"] = types.ModuleType("__main__")
    try:
        yield
    finally:
        sys.modules["__main__"] = real
