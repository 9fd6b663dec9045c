"""A `tidelink` CLI subprocess for the launcher tests: its own session, lines read by threads.

`wait_for` blocks on a condition variable until a line matches (or the process ends, or the
timeout passes), so the tests synchronise on what the launcher prints, never on sleeps.
"""

from __future__ import annotations

import contextlib
import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path
from types import TracebackType
from typing import IO

REPO = Path(__file__).resolve().parents[2]


def tidelink_check(*args: str) -> subprocess.CompletedProcess[str]:
    """`tidelink check ARGS` to its end (output captured): how a new user meets a bad config."""
    return tidelink_cli("check", *args)


def tidelink_cli(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    """`tidelink ARGS` to its end (output captured, timeout_s at most)."""
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        capture_output=True,
        text=True,
        timeout=timeout_s,
        cwd=REPO,
        check=False,
    )


class Tidelink:
    """`python -m services.cli ARGS` (optionally inside a network namespace)."""

    def __init__(self, *args: str, netns: str | None = None, cli: bool = True) -> None:
        cmd = [sys.executable, *(("-m", "services.cli") if cli else ()), *args]
        if netns is not None:
            cmd = ["ip", "netns", "exec", netns, *cmd]
        # faulthandler: a process that hangs dumps every thread's stack on SIGABRT (see wait)
        env = dict(os.environ, PYTHONUNBUFFERED="1", PYTHONFAULTHANDLER="1")
        # the tests directory too: `Tidelink.python("-m", "helpers.X")` runs a test helper
        paths = [str(REPO), str(REPO / "tests"), env.get("PYTHONPATH")]
        env["PYTHONPATH"] = os.pathsep.join(p for p in paths if p)
        self.cmd = cmd
        self.proc = subprocess.Popen(
            cmd,
            cwd=REPO,
            env=env,
            text=True,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )
        self.out: list[str] = []
        self.err: list[str] = []
        self._cond = threading.Condition()
        self._open = 2
        pipes = ((self.proc.stdout, self.out), (self.proc.stderr, self.err))
        self._threads = [
            threading.Thread(target=self._read, args=(s, lines), daemon=True) for s, lines in pipes
        ]
        for t in self._threads:
            t.start()

    @classmethod
    def python(cls, *args: str) -> Tidelink:
        """`python ARGS` with the same pipes and clean-up (a helper process of a test)."""
        return cls(*args, cli=False)

    def _read(self, stream: IO[str] | None, lines: list[str]) -> None:
        assert stream is not None
        for line in stream:
            with self._cond:
                lines.append(line.rstrip("\n"))
                self._cond.notify_all()
        with self._cond:
            self._open -= 1
            self._cond.notify_all()

    def wait_for(
        self, pattern: str, timeout_s: float, *, start: int = 0, stdout: bool = False
    ) -> re.Match[str]:
        """The first stderr (or stdout) line from index `start` on that matches `pattern`."""
        rx = re.compile(pattern)
        lines = self.out if stdout else self.err

        def found() -> re.Match[str] | None:
            for line in lines[start:]:
                if m := rx.search(line):
                    return m
            return None

        with self._cond:
            self._cond.wait_for(lambda: found() is not None or self._open == 0, timeout_s)
            m = found()
        if m is None:
            raise AssertionError(
                f"no line matching {pattern!r} within {timeout_s} s "
                f"(exit code {self.proc.poll()}); stderr:\n{self.stderr}"
            )
        return m

    def wait(self, timeout_s: float) -> int:
        """The exit code within timeout_s; a process still running then is a hang: it is made
        to dump every thread's stack (SIGABRT, faulthandler) and the AssertionError shows it."""
        try:
            code = self.proc.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):  # it may have ended just now
                os.killpg(self.proc.pid, signal.SIGABRT)
            self.proc.wait(timeout=15.0)
            for t in self._threads:
                t.join(timeout=15.0)
            raise AssertionError(
                f"{' '.join(self.cmd)} still running after {timeout_s} s; "
                f"its stacks and stderr:\n{self.stderr[-12000:]}"
            ) from None
        for t in self._threads:
            t.join(timeout=timeout_s)
        return code

    @property
    def stderr(self) -> str:
        with self._cond:
            return "\n".join(self.err)

    @property
    def stdout(self) -> str:
        with self._cond:
            return "\n".join(self.out)

    def signal(self, sig: int) -> None:
        self.proc.send_signal(sig)

    def __enter__(self) -> Tidelink:
        return self

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
        self.wait(15.0)


def alive(pid: int) -> bool:
    """True if pid runs (a zombie has ended: its parent just has not reaped it)."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except FileNotFoundError:
        return False


def wait_dead(pids: list[int], timeout_s: float) -> list[int]:
    """Wait until these processes (children of anyone) have ended, on their pidfds (readable
    once a process exits); the ones still running after timeout_s."""
    deadline = time.monotonic() + timeout_s
    left = []
    for pid in pids:
        try:
            fd = os.pidfd_open(pid)
        except ProcessLookupError:
            continue
        try:
            ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
            if not ready and alive(pid):
                left.append(pid)
        finally:
            os.close(fd)
    return left


def processes_mentioning(text: str) -> list[int]:
    """Live pids whose command line contains `text` (e.g. a run's output folder)."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit():
            continue
        try:
            cmdline = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if text in cmdline and alive(int(d.name)):
            out.append(int(d.name))
    return out


def kill_recorded(pid_file: Path) -> None:
    """Teardown: SIGKILL every process a launch recorded in pids.json that still runs."""
    import json

    if not pid_file.exists():
        return
    data = json.loads(pid_file.read_text())
    for pids in data.get("processes", {}).values():
        for pid in pids:
            if alive(pid):
                try:
                    os.killpg(pid, signal.SIGKILL)
                except (ProcessLookupError, PermissionError):
                    pass


def judged_exit(out: Path) -> int:
    """The exit code a finished `run`/`launch` owes its metrics.json: 0 when the mission
    succeeded, 3 when it was judged failed (contact, inside rho0, goal not reached). For tests
    whose subject is not the mission's outcome (recording, monitoring, placement): they check
    that the run ended as its own metrics say, whichever way the mission went."""
    import json

    m = json.loads((out / "metrics.json").read_text())
    return 0 if m.get("success", True) else 3
