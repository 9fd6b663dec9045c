"""Child service processes: spawn with a log file, stop politely then firmly, report deaths."""

from __future__ import annotations

import contextlib
import multiprocessing
import os
import signal
import socket
import subprocess
import sys
import time
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Protocol

from common.config.bus import tcp_address
from common.runtime.processes.forkserver import fork_module
from common.runtime.processes.parent_death import die_with


def connectable(endpoint: str) -> str:
    """The endpoint a process on this machine dials for a listen endpoint (wildcards: loopback)."""
    return endpoint.replace("0.0.0.0", "127.0.0.1").replace("[::]", "127.0.0.1")


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (the OS picks it)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def port_free(endpoint: str) -> bool:
    """Whether a tcp/ or tls/HOST:PORT endpoint could be listened on now: nothing listens on
    its port (a bind as a listener makes it, with SO_REUSEADDR, so connections of an earlier
    listener left in TIME_WAIT do not count). False for any other endpoint."""
    address = tcp_address(endpoint)
    if address is None:
        return False
    family = socket.AF_INET6 if ":" in address[0] else socket.AF_INET
    with socket.socket(family, socket.SOCK_STREAM) as s:
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            s.bind(address)
        except OSError:
            return False
    return True


def how_it_ended(code: int | None) -> str:
    """'exited with code 3', 'was killed by signal 9' or 'is still running'."""
    if code is None:
        return "is still running"
    return f"was killed by signal {-code}" if code < 0 else f"exited with code {code}"


def wait_for_endpoint(endpoint: str, timeout_s: float) -> bool:
    """Wait until a tcp/ or tls/HOST:PORT endpoint accepts TCP connections (a service started
    before its router); True when it does, False on timeout. Other protocols are not probed:
    True."""
    address = tcp_address(endpoint)
    if address is None:
        return True
    deadline = time.monotonic() + timeout_s
    while True:
        try:
            with socket.create_connection(address, timeout=1.0):
                return True
        except OSError:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.2)


class ProcessHandle(Protocol):
    """What we use of a child process: subprocess.Popen, or a forked one (ForkedProcess)."""

    @property
    def pid(self) -> int: ...

    @property
    def returncode(self) -> int | None: ...

    def poll(self) -> int | None: ...

    def wait(self, timeout: float | None = None) -> int: ...

    def send_signal(self, sig: int) -> None: ...


@dataclass
class Child:
    """One service process and its log file."""

    name: str
    proc: ProcessHandle
    log_path: Path
    _log: object = field(default=None, repr=False)
    group: bool = False  # leads its own process group: signals go to the whole group

    def signal(self, sig: int) -> None:
        """Send sig to the process, or to its whole process group if it leads one."""
        with contextlib.suppress(ProcessLookupError, PermissionError):
            if self.group:
                os.killpg(self.proc.pid, sig)
            else:
                self.proc.send_signal(sig)

    def close_log(self) -> None:
        """Close our handle on its log file (the process keeps its own)."""
        if self._log is not None:
            with contextlib.suppress(Exception):
                self._log.close()  # type: ignore[attr-defined]

    def tail(self, n: int = 12) -> str:
        """The last lines of its log, for error reports."""
        try:
            with self.log_path.open("r", errors="replace") as fh:
                return "".join(deque(fh, maxlen=n))
        except OSError:
            return ""

    def describe_exit(self) -> str:
        how = how_it_ended(self.proc.poll())
        tail = self.tail()
        return f"service {self.name!r} {how}" + (f"; last log lines:\n{tail}" if tail else "")


def spawn(
    name: str,
    args: list[str],
    log_dir: Path,
    env: dict[str, str] | None = None,
    *,
    group: bool = False,
    append: bool = False,
) -> Child:
    """Start `python -m ...args` with stdout and stderr into log_dir/<name>.log.

    group=True starts it in a new session (its own process group), so a terminal's Ctrl-C
    reaches only the parent, which then stops the child's whole group in order (stop_all).
    append=True keeps an earlier log of the same name (a restarted service).
    """
    log_dir.mkdir(parents=True, exist_ok=True)
    log_path = log_dir / f"{name}.log"
    fh = log_path.open("ab" if append else "wb")
    full_env = dict(os.environ)
    full_env.update(env or {})
    full_env.setdefault("PYTHONUNBUFFERED", "1")
    proc = subprocess.Popen(
        [sys.executable, *args],
        stdout=fh,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        env=full_env,
        start_new_session=group,
        preexec_fn=die_with(os.getpid()),
    )
    return Child(name, proc, log_path, fh, group)


def fork(
    name: str,
    module: str,
    argv: list[str],
    log_dir: Path,
    *,
    group: bool = False,
    append: bool = False,
) -> Child:
    """Start `module.main(argv)` forked from the pre-imported fork server (forkserver.py),
    logging to log_dir/<name>.log: like spawn(name, ["-m", module, *argv], group=group),
    without the interpreter start-up and imports. For local service processes of a run.
    append=True keeps an earlier log of the same name (a restarted service).

    In a daemonic process (a Dask worker running a sweep's run, say), which multiprocessing
    forbids to have children of its own, it is exactly that spawn instead.
    """
    if multiprocessing.current_process().daemon:
        return spawn(name, ["-m", module, *argv], log_dir, group=group, append=append)
    log_dir.mkdir(parents=True, exist_ok=True)
    log_path = log_dir / f"{name}.log"
    proc = fork_module(module, argv, log_path, append=append, group=group)
    return Child(name, proc, log_path, group=group)


def stop_all(children: list[Child], *, grace_s: float = 3.0) -> None:
    """SIGINT, then SIGTERM, then SIGKILL, each after a grace period; always reaps.

    Children that lead a process group are signalled as a group; after the leader is gone a
    last SIGKILL to its group takes any process it left behind.
    """
    for sig, wait_s in ((signal.SIGINT, grace_s), (signal.SIGTERM, grace_s), (signal.SIGKILL, 5.0)):
        alive = [c for c in children if c.proc.poll() is None]
        if not alive:
            break
        for c in alive:
            c.signal(sig)
        deadline = time.monotonic() + wait_s
        for c in alive:
            with contextlib.suppress(subprocess.TimeoutExpired):
                c.proc.wait(timeout=max(0.0, deadline - time.monotonic()))
    for c in children:
        if c.group:
            c.signal(signal.SIGKILL)  # the leader is reaped; anything left in its group goes
        c.close_log()
