"""Supervise named OS processes: restart them by policy with back-off, report exits, stop all.

Processes are either spawned (children.spawn) or forked from the pre-imported fork server
(children.fork: a run's services, ready in milliseconds, a restarted one too), each leading
its own process group, so a terminal's Ctrl-C reaches only the launcher, which then stops
every group in order: SIGINT, SIGTERM, SIGKILL, each after a grace period. Nothing here
blocks: `poll()` is called from the driver's loop and returns what happened since the last
call.
"""

from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from common.runtime.processes.children import Child, fork, how_it_ended, spawn, stop_all
from common.runtime.processes.policy import RestartPolicy


class ServiceFailed(RuntimeError):
    """A service process of the run died or stopped answering; the message names it."""


@dataclass(frozen=True, kw_only=True)
class _Ended:
    """A supervised process ended; `text` names it, says how, and quotes its last log lines."""

    name: str
    code: int
    text: str


@dataclass(frozen=True, kw_only=True)
class Exited(_Ended):
    """A supervised process ended (what follows says whether it restarts)."""


@dataclass(frozen=True, kw_only=True)
class GaveUp(_Ended):
    """A process ended and its policy does not restart it: the run cannot go on without it."""


@dataclass(frozen=True, kw_only=True)
class Restarting:
    """A process that exited will be started again after `delay_s` (restart n of max)."""

    name: str
    attempt: int
    max_restarts: int
    delay_s: float


@dataclass(frozen=True, kw_only=True)
class Restarted:
    """A process was started again (its new pid)."""

    name: str
    attempt: int
    pid: int


Event = Exited | Restarting | Restarted | GaveUp


@dataclass
class _Entry:
    name: str
    args: list[str]
    policy: RestartPolicy
    child: Child
    restarts: int = 0
    restart_at: float | None = None  # monotonic time of a scheduled restart
    reported: bool = False  # this incarnation's exit has been seen
    pids: list[int] = field(default_factory=list)
    never_because: str = ""  # why this process is never restarted, whatever the policies
    forked: bool = False  # forked from the fork server (else spawned), restarts too


class Supervisor:
    """Starts named processes and keeps them running according to their restart policies."""

    def __init__(
        self,
        log_dir: Path,
        *,
        pid_file: Path | None = None,
        clock: Callable[[], float] = time.monotonic,
        forked: bool = False,
    ) -> None:
        self.log_dir = log_dir
        self.forked = forked  # fork from the fork server instead of spawning an interpreter
        self.pid_file = pid_file
        self.clock = clock
        self.stopping = False  # set when the run ends: exits are expected, nothing restarts
        self._entries: dict[str, _Entry] = {}

    @property
    def children(self) -> dict[str, Child]:
        """The current process of every supervised name, in start order."""
        return {n: e.child for n, e in self._entries.items()}

    def names(self) -> list[str]:
        return list(self._entries)

    def restarts(self, name: str) -> int:
        return self._entries[name].restarts

    def pending_restart(self, name: str) -> bool:
        """True while `name` waits out its back-off before a restart."""
        e = self._entries.get(name)
        return e is not None and e.restart_at is not None

    def pids(self, name: str) -> list[int]:
        """Every pid this name has had, first to last."""
        return list(self._entries[name].pids)

    def start(
        self,
        name: str,
        args: list[str],
        policy: RestartPolicy | None = None,
        *,
        never_because: str = "",
        spawned: bool = False,
    ) -> Child:
        """Start `python <args>` as `name`, logging to log_dir/<name>.log (forked: the args
        must be `-m MODULE ...`, whose `main(argv)` runs in the forked process).
        `never_because`: this process is never restarted, and its exit says why. `spawned`:
        a fresh interpreter even here (one that needs none of the fork server's imports and
        should not wait for them, the router)."""
        if name in self._entries:
            raise ValueError(f"{name!r} is already supervised")
        forked = self.forked and not spawned
        if forked and args[:1] != ["-m"]:
            raise ValueError(f"{name}: a forked process runs a module: expected -m MODULE ...")
        child = self._launch(name, args, forked=forked, append=False)
        self._entries[name] = _Entry(
            name,
            args,
            policy or RestartPolicy(),
            child,
            pids=[child.proc.pid],
            never_because=never_because,
            forked=forked,
        )
        self._write_pids()
        return child

    def forget(self, name: str) -> None:
        """Stop supervising `name`, which has exited (one that never got going, such as a
        router whose port was taken), so the name can be started again."""
        e = self._entries[name]
        if e.child.proc.poll() is None:
            raise ValueError(f"{name!r} is still running")
        e.child.close_log()
        del self._entries[name]
        self._write_pids()

    def poll(self) -> list[Event]:
        """Notice exits, schedule restarts with back-off, and start those that are due."""
        events: list[Event] = []
        now = self.clock()
        for e in self._entries.values():
            if e.restart_at is not None:
                if now >= e.restart_at and not self.stopping:
                    events.append(self._restart(e))
                continue
            code = e.child.proc.poll()
            if code is None or e.reported:
                continue
            e.reported = True
            if not self.stopping:
                events.extend(self._exited(e, code, now))
        return events

    def _exited(self, e: _Entry, code: int, now: float) -> list[Event]:
        how = f"service {e.name!r} {how_it_ended(code)}"
        tail = e.child.tail().rstrip()
        quoted = f"; last log lines:\n{tail}" if tail else ""
        exited = Exited(name=e.name, code=code, text=how + quoted)
        if e.policy.should_restart(code, e.restarts):
            delay = e.policy.delay_s(e.restarts)
            e.restart_at = now + delay
            return [
                exited,
                Restarting(
                    name=e.name,
                    attempt=e.restarts + 1,
                    max_restarts=e.policy.max_restarts,
                    delay_s=delay,
                ),
            ]
        if e.never_because:
            why = e.never_because
        elif e.policy.mode == "never":
            why = "restart policy 'never'"
        elif e.policy.mode == "on-failure" and code == 0:
            why = "restart policy 'on-failure' does not restart exit code 0"
        else:
            why = f"gave up after {e.restarts} restarts"
        return [exited, GaveUp(name=e.name, code=code, text=f"{how} ({why}){quoted}")]

    def _restart(self, e: _Entry) -> Restarted:
        e.restart_at = None
        e.restarts += 1
        e.child.close_log()
        with e.child.log_path.open("a") as fh:  # where each incarnation starts
            fh.write(f"--- {time.strftime('%H:%M:%S')} restart {e.restarts} of {e.name!r} ---\n")
        e.child = self._launch(e.name, e.args, forked=e.forked, append=True)
        e.reported = False
        e.pids.append(e.child.proc.pid)
        self._write_pids()
        return Restarted(name=e.name, attempt=e.restarts, pid=e.child.proc.pid)

    def _launch(self, name: str, args: list[str], *, forked: bool, append: bool) -> Child:
        if forked:
            return fork(name, args[1], args[2:], self.log_dir, group=True, append=append)
        return spawn(name, args, self.log_dir, group=True, append=append)

    def wait_exited(self, names: list[str], timeout_s: float) -> bool:
        """Wait until these processes have exited by themselves; False on timeout."""
        deadline = time.monotonic() + timeout_s
        for n in names:
            left = max(0.0, deadline - time.monotonic())
            try:
                self._entries[n].child.proc.wait(timeout=left)
            except Exception:  # noqa: BLE001 - subprocess.TimeoutExpired: stop_all will see to it
                return False
        return True

    def stop(self, names: list[str] | None = None, *, grace_s: float = 3.0) -> None:
        """Stop these (default: all, last started first) groups: SIGINT, SIGTERM, SIGKILL."""
        self.stopping = True
        order = list(reversed(self._entries)) if names is None else names
        for e in (self._entries[n] for n in order):
            e.restart_at = None
        stop_all([self._entries[n].child for n in order], grace_s=grace_s)

    def stop_in_order(self, first: list[str], then: list[str], *, grace_s: float = 3.0) -> None:
        """Stop `first` together, then `then` (e.g. the services, then the router)."""
        self.stop([n for n in first if n in self._entries], grace_s=grace_s)
        self.stop([n for n in then if n in self._entries], grace_s=grace_s)

    def _write_pids(self) -> None:
        """pids.json: the launcher's pid and every pid each name has had (for ops and tests)."""
        if self.pid_file is None:
            return
        data = {"launcher": os.getpid(), "processes": {n: e.pids for n, e in self._entries.items()}}
        tmp = self.pid_file.with_suffix(".tmp")
        tmp.write_text(json.dumps(data, indent=1))
        tmp.replace(self.pid_file)
