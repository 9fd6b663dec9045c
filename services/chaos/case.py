"""One case of the fault matrix: a real `tidelink launch`, the fault applied mid-mission,
and what came of it (exit code, metrics, processes left behind)."""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.bus import Keys
from common.runtime.model.dataflow import Dataflow
from common.runtime.processes.children import free_port
from services.chaos.faults import OUTSIDE, ROUTER, Fault
from services.chaos.inject import inject
from services.chaos.outside import OutsideFault, OutsideReport
from services.mission.records import AuvRun, read_metrics

PROGRESS = re.compile(r"t=\s*([0-9.]+) s of")
STOPPED = "mission clock started"
PROGRESS_EVERY_S = 0.25  # wall seconds between the launch's progress lines (PROGRESS)


@dataclass(frozen=True)
class CaseSetup:
    """How every case runs: the scenario and its --set, the speed, when faults strike."""

    scenario: Path
    sets: tuple[str, ...] = ()
    time_scale: float = 4.0
    fault_at_s: float = 15.0  # mission time the fault strikes at
    timeout_s: float = 240.0  # wall time a case may take before it counts as a hang


@dataclass
class Outcome:
    """What a case produced."""

    fault: Fault
    exit_code: int | None  # None: it hung (killed after the timeout)
    metrics: AuvRun | None = None  # None: no metrics.json (or none this version reads)
    leftovers: list[str] = field(default_factory=list)  # "name pid" of each left running
    wall_s: float = 0.0
    injected: int = 0
    note: str = ""
    # a fault from outside the loop: what its processes did (services/chaos/outside.py)
    outside: OutsideReport = field(default_factory=OutsideReport)
    alarms: list[str] = field(default_factory=list)  # the launcher's ALARM lines


class _Lines:
    """The launcher's output lines, read by a thread; waits on a condition, not sleeps."""

    def __init__(self, proc: subprocess.Popen[str]) -> None:
        self.lines: list[str] = []
        self.cond = threading.Condition()
        self.proc = proc
        assert proc.stderr is not None
        threading.Thread(target=self._read, args=(proc.stderr,), daemon=True).start()

    def _read(self, stream: Any) -> None:
        for line in stream:
            with self.cond:
                self.lines.append(line.rstrip("\n"))
                self.cond.notify_all()
        with self.cond:
            self.cond.notify_all()

    def wait_for(self, pred: Any, timeout_s: float) -> bool:
        with self.cond:
            return bool(
                self.cond.wait_for(
                    lambda: any(pred(x) for x in self.lines) or self.proc.poll() is not None,
                    timeout_s,
                )
                and any(pred(x) for x in self.lines)
            )


def _at_least(t: float) -> Any:
    def pred(line: str) -> bool:
        m = PROGRESS.search(line)
        return m is not None and float(m.group(1)) >= t

    return pred


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as fh:
            return fh.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (FileNotFoundError, IndexError):
        return False


def _pids(out: Path) -> dict[str, list[int]]:
    try:
        return dict(json.loads((out / "pids.json").read_text())["processes"])
    except (OSError, ValueError, KeyError):
        return {}


def run_case(setup: CaseSetup, fault: Fault, out: Path, keys: Keys, flow: Dataflow) -> Outcome:
    """Launch, strike, wait for the end; every process of the case is gone on return."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    argv = [sys.executable, "-m", "services.cli", "launch", str(setup.scenario)]
    argv += ["--listen", endpoint, "--time-scale", f"{setup.time_scale:g}"]
    # the fault strikes at the first progress line past fault_at_s: one every PROGRESS_EVERY_S
    # of wall time, so that under load it still lands near its time, not seconds later
    argv += ["--out", str(out), "--no-plot", "--json", "--progress-every", f"{PROGRESS_EVERY_S:g}"]
    for s in setup.sets:
        argv += ["--set", s]
    if fault.restart:
        argv += ["--restart", f"{fault.target}=on-failure:3", "--backoff", "0.2"]
    outside = None
    if fault.kind in OUTSIDE:
        outside = OutsideFault(
            fault.kind,
            fault.target,
            fault.hold_s,
            out,
            endpoint,
            setup.scenario,
            setup.sets,
            setup.time_scale,
        )
        argv += outside.launch_args()
    t0 = time.monotonic()
    proc = subprocess.Popen(
        argv,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        text=True,
        start_new_session=True,
        env=dict(os.environ, PYTHONUNBUFFERED="1"),
    )
    lines = _Lines(proc)
    outcome = Outcome(fault=fault, exit_code=None)
    try:
        if outside is not None:
            outside.start()
        if not lines.wait_for(_at_least(setup.fault_at_s), setup.timeout_s):
            outcome.note = f"the run never reached t={setup.fault_at_s:g} s"
        elif outside is not None:
            outcome.injected = outside.strike(keys, flow)
        else:
            outcome.injected = _strike(setup, fault, proc, out, endpoint, keys, flow)
        try:
            outcome.exit_code = proc.wait(max(1.0, setup.timeout_s - (time.monotonic() - t0)))
        except subprocess.TimeoutExpired:
            outcome.note = outcome.note or f"hung: no end within {setup.timeout_s:g} s"
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
        outcome.wall_s = time.monotonic() - t0
        outcome.leftovers = _leftovers(out)
        stdout = proc.stdout.read() if proc.stdout else ""
        if outside is not None:
            outcome.outside = outside.finish()
    outcome.alarms = [x for x in lines.lines if "ALARM" in x]
    outcome.metrics = _metrics(out)
    del stdout  # --json's copy of metrics.json; the file is what a user would read
    if outcome.exit_code is not None and outcome.exit_code != 0 and not outcome.note:
        outcome.note = next((x for x in reversed(lines.lines) if "error" in x), "")[-160:]
    return outcome


def _strike(
    setup: CaseSetup,
    fault: Fault,
    proc: subprocess.Popen[str],
    out: Path,
    endpoint: str,
    keys: Keys,
    flow: Dataflow,
) -> int:
    """Apply the fault; returns the frames injected (0 for process faults)."""
    if fault.kind == "kill_launcher":
        os.kill(proc.pid, signal.SIGKILL)
        return 0
    if fault.kind == "inject":
        window_s = 10.0 / setup.time_scale  # ten mission seconds of it
        return inject(
            endpoint,
            keys,
            flow,
            fault.target,
            window_s=window_s,
            running=lambda: proc.poll() is None,
        )
    pid = _pids(out).get(fault.target if fault.target != ROUTER else ROUTER, [0])[-1]
    if not pid:
        raise RuntimeError(f"no pid for {fault.target} in {out / 'pids.json'}")
    if fault.kind == "kill":
        os.kill(pid, signal.SIGKILL)
        return 0
    os.kill(pid, signal.SIGSTOP)
    try:
        time.sleep(fault.hold_s / setup.time_scale)  # the stop's length is the fault itself
    finally:
        os.kill(pid, signal.SIGCONT)
    return 0


def _leftovers(out: Path) -> list[str]:
    """Processes of the case still running ("name pid") a moment after its launcher ended."""
    named = [(n, p) for n, ps in _pids(out).items() for p in ps]
    deadline = time.monotonic() + 10.0
    left = [(n, p) for n, p in named if _alive(p)]
    while left and time.monotonic() < deadline:
        time.sleep(0.1)  # processes given 10 s to go; polling /proc, not a result
        left = [(n, p) for n, p in left if _alive(p)]
    for _, p in left:
        try:
            os.killpg(p, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
    return [f"{n} {p}" for n, p in left]


def _metrics(out: Path) -> AuvRun | None:
    try:
        return read_metrics(out / "metrics.json")
    except (OSError, ValueError):  # msgspec.ValidationError and MetricsSchemaError too
        return None
