"""The launcher's restart policies and process supervision (plain child processes, no Zenoh).

Restart back-off is checked against an injected clock, so nothing here waits on wall time;
the stop escalation waits on a FIFO the child writes once its signal handlers are set.
"""

from __future__ import annotations

import json
import os
import select
import signal
from pathlib import Path

import pytest
from hypothesis import given
from hypothesis import strategies as st

from common.runtime.processes.policy import RestartPolicy, parse_restart, policies_for
from common.runtime.processes.signals import STOP_DEADLINE_S
from common.runtime.processes.supervisor import Exited, GaveUp, Restarted, Restarting, Supervisor

WAIT_S = 15.0


class FakeClock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def _exit_with(code: int, text: str = "") -> list[str]:
    return ["-c", f"import sys; print({text!r}); sys.exit({code})"]


# -- policies ----------------------------------------------------------------------------------
@given(backoff=st.floats(0.0, 10.0), cap=st.floats(10.0, 100.0), n=st.integers(0, 20))
def test_back_off_doubles_until_the_cap(backoff: float, cap: float, n: int) -> None:
    p = RestartPolicy(mode="on-failure", backoff_s=backoff, backoff_max_s=cap)
    assert p.delay_s(0) == backoff
    assert p.delay_s(n + 1) == pytest.approx(min(cap, 2.0 * p.delay_s(n)))
    assert p.delay_s(n) <= cap


def test_which_exits_each_mode_restarts() -> None:
    never = RestartPolicy(mode="never")
    on_failure = RestartPolicy(mode="on-failure", max_restarts=2)
    always = RestartPolicy(mode="always", max_restarts=2)
    assert not never.should_restart(3, 0)
    assert on_failure.should_restart(3, 0) and on_failure.should_restart(-9, 1)
    assert not on_failure.should_restart(0, 0)  # a clean exit is not a failure
    assert not on_failure.should_restart(3, 2)  # max_restarts used up
    assert always.should_restart(0, 1) and not always.should_restart(0, 2)


def test_restart_options_parse_per_service() -> None:
    default = RestartPolicy(backoff_s=0.25)
    assert parse_restart("always", default) == (None, RestartPolicy(mode="always", backoff_s=0.25))
    name, p = parse_restart("filter=on-failure:5", default)
    assert (name, p.mode, p.max_restarts, p.backoff_s) == ("filter", "on-failure", 5, 0.25)
    got = policies_for(("a", "b"), ["on-failure", "b=never"], default)
    assert (got["a"].mode, got["b"].mode) == ("on-failure", "never")
    for bad in ("sometimes", "a=on-failure:x", "=always"):
        with pytest.raises(ValueError, match="--restart"):
            policies_for(("a",), [bad], default)
    with pytest.raises(ValueError, match="unknown service 'c'"):
        policies_for(("a",), ["c=always"], default)
    # the router gets a policy only by its name: a bare MODE is the services'
    got = policies_for(("a",), ["router=on-failure", "always"], default, named_only=("router",))
    assert (got["a"].mode, got["router"].mode) == ("always", "on-failure")
    assert "router" not in policies_for(("a",), ["always"], default, named_only=("router",))
    with pytest.raises(ValueError, match="backoff_s"):
        RestartPolicy(backoff_s=5.0, backoff_max_s=1.0)


# -- supervision -------------------------------------------------------------------------------
def _poll_after_exit(sup: Supervisor, name: str) -> list[object]:
    sup.children[name].proc.wait(timeout=WAIT_S)
    return list(sup.poll())


@pytest.mark.slow  # real child processes (no Zenoh), ~1 s in all
def test_on_failure_restarts_with_doubling_back_off_then_gives_up(tmp_path: Path) -> None:
    clock = FakeClock()
    sup = Supervisor(tmp_path / "logs", pid_file=tmp_path / "pids.json", clock=clock)
    policy = RestartPolicy(mode="on-failure", max_restarts=2, backoff_s=0.5)
    sup.start("svc", _exit_with(3, "boom"), policy)
    delays = []
    for attempt in (1, 2):
        exited, restarting = _poll_after_exit(sup, "svc")
        assert isinstance(exited, Exited) and exited.code == 3
        assert "service 'svc' exited with code 3" in exited.text and "boom" in exited.text
        assert isinstance(restarting, Restarting) and restarting.attempt == attempt
        delays.append(restarting.delay_s)
        clock.t += restarting.delay_s * 0.99
        assert sup.poll() == []  # still backing off: nothing started
        clock.t += restarting.delay_s * 0.02
        (restarted,) = sup.poll()
        assert isinstance(restarted, Restarted) and restarted.attempt == attempt
    assert delays == [0.5, 1.0]  # doubling
    exited, gave_up = _poll_after_exit(sup, "svc")
    assert isinstance(gave_up, GaveUp)
    assert "service 'svc' exited with code 3 (gave up after 2 restarts)" in gave_up.text
    pids = json.loads((tmp_path / "pids.json").read_text())
    assert pids["launcher"] == os.getpid()
    assert len(pids["processes"]["svc"]) == 3 == len(set(pids["processes"]["svc"]))
    log = (tmp_path / "logs" / "svc.log").read_text()
    assert log.count("boom") == 3  # a restart appends to the same log
    sup.stop()


@pytest.mark.slow  # real child processes (no Zenoh), ~1 s in all
def test_never_and_clean_exits(tmp_path: Path) -> None:
    sup = Supervisor(tmp_path, clock=FakeClock())
    sup.start("a", _exit_with(4, "last words"))  # default policy: never
    sup.start("b", _exit_with(0), RestartPolicy(mode="on-failure"))
    sup.start("c", _exit_with(0), RestartPolicy(mode="always", backoff_s=0.0))
    for name in ("a", "b", "c"):
        sup.children[name].proc.wait(timeout=WAIT_S)
    events = sup.poll()
    gave_up = {e.name: e.text for e in events if isinstance(e, GaveUp)}
    assert gave_up["a"].startswith("service 'a' exited with code 4 (restart policy 'never')")
    assert "last words" in gave_up["a"]
    assert "does not restart exit code 0" in gave_up["b"]
    assert any(isinstance(e, Restarting) and e.name == "c" for e in events)
    assert "c" not in gave_up
    sup.stop()
    assert all(c.proc.poll() is not None for c in sup.children.values())


STUBBORN = """
import os, signal, subprocess, sys
signal.signal(signal.SIGINT, signal.SIG_IGN)
signal.signal(signal.SIGTERM, signal.SIG_IGN)
grandchild = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(600)"])
with open(sys.argv[1], "w") as fifo:
    fifo.write(f"{grandchild.pid}\\n")
signal.pause()
"""


def _ends_within(pid: int, timeout_s: float) -> bool:
    """True once the process has ended (a pidfd turns readable), False after timeout_s."""
    try:
        fd = os.pidfd_open(pid)
    except ProcessLookupError:
        return True
    try:
        ready, _, _ = select.select([fd], [], [], timeout_s)
        return bool(ready)
    finally:
        os.close(fd)


def _ready_fifo(tmp_path: Path) -> tuple[Path, int]:
    """A FIFO the child writes once it is ready, and our non-blocking end of it (select on
    it instead of sleeping)."""
    fifo = tmp_path / "ready"
    os.mkfifo(fifo)
    return fifo, os.open(fifo, os.O_RDONLY | os.O_NONBLOCK)


@pytest.mark.slow  # real child processes (no Zenoh), ~1 s in all
def test_stop_escalates_to_sigkill_for_the_whole_group(tmp_path: Path) -> None:
    fifo, reader = _ready_fifo(tmp_path)
    sup = Supervisor(tmp_path)
    child = sup.start("stubborn", ["-c", STUBBORN, str(fifo)])
    try:
        data = b""
        while not data.endswith(b"\n"):
            ready, _, _ = select.select([reader], [], [], WAIT_S)
            assert ready, "the child never reported its grandchild"
            data += os.read(reader, 64)
        grandchild = int(data)
        assert os.getpgid(grandchild) == child.proc.pid  # same process group as the child
        sup.stop(grace_s=0.3)
        assert child.proc.returncode == -signal.SIGKILL  # SIGINT and SIGTERM were ignored
        assert _ends_within(grandchild, WAIT_S)
    finally:
        os.close(reader)
        sup.stop(grace_s=0.1)


@pytest.mark.slow  # real child processes (no Zenoh), ~1 s in all
def test_a_child_leads_its_own_process_group(tmp_path: Path) -> None:
    fifo, reader = _ready_fifo(tmp_path)
    sup = Supervisor(tmp_path)
    # Python's own SIGINT handler, set explicitly: a suite started in the background by a
    # shell inherits SIGINT ignored, and so would this child (then SIGTERM ends it); the
    # stop waits until it is set (a SIGINT before it was ignored, seen in such a suite).
    # 'ready' is flushed and its file kept open: written as open(...).write(...), it reached
    # us when the file was closed at deallocation, and a SIGINT landing in that close was
    # lost (the handler set, nothing pending, the child still waiting; ended by SIGTERM in 1
    # of 2 runs started from a background job, 0 of 10 this way). Then the wait of a service
    # (wait_for_stop): signal.pause() misses a signal that lands just before it.
    quiet = (
        "import signal, sys; from common.runtime.processes.signals import wait_for_stop; "
        "signal.signal(signal.SIGINT, signal.default_int_handler); "
        "ready = open(sys.argv[1], 'w'); ready.write('ready\\n'); ready.flush(); wait_for_stop()"
    )
    child = sup.start("quiet", ["-c", quiet, str(fifo)])
    try:
        assert os.getpgid(child.proc.pid) == child.proc.pid != os.getpgid(0)
        ready, _, _ = select.select([reader], [], [], WAIT_S)
        assert ready, "the child never set its SIGINT handler"
    finally:
        os.close(reader)
        sup.stop(grace_s=5.0)
    assert child.proc.returncode == -signal.SIGINT  # the first, polite signal was enough


HANGING_STOP = """
import sys, time
from common.runtime.processes.signals import Shutdown, install_shutdown_handlers
install_shutdown_handlers()
open(sys.argv[1], "w").write("ready\\n")
try:
    time.sleep(60)
except Shutdown:
    time.sleep(60)  # an orderly stop that hangs, as a Zenoh close with its router gone did
"""


@pytest.mark.slow  # a real child process (no Zenoh), ~5 s: the deadline itself
def test_an_orderly_stop_that_hangs_ends_at_its_deadline(tmp_path: Path) -> None:
    """One SIGTERM is all a child gets when its parent dies (the parent-death signal): a
    stop that hangs must still end the process, by the kernel, STOP_DEADLINE_S later."""
    fifo, reader = _ready_fifo(tmp_path)
    sup = Supervisor(tmp_path)
    child = sup.start("hanging", ["-c", HANGING_STOP, str(fifo)])
    try:
        ready, _, _ = select.select([reader], [], [], WAIT_S)
        assert ready, "the child never installed its handlers"
        child.proc.send_signal(signal.SIGTERM)
        assert child.proc.wait(STOP_DEADLINE_S + WAIT_S) == -signal.SIGALRM
    finally:
        os.close(reader)
        sup.stop(grace_s=0.1)


SIGNAL_ON_ANOTHER_THREAD = """
import sys, threading, signal, time
from common.runtime.processes.signals import Shutdown, install_shutdown_handlers, wait_for_stop
install_shutdown_handlers()
main = threading.main_thread().native_id
waiting = threading.Event()

def elsewhere() -> None:
    waiting.wait()
    # until the main thread sleeps (in wait_for_stop's select), polling its state in /proc
    while open(f"/proc/self/task/{main}/stat").read().rsplit(")", 1)[1].split()[0] != "S":
        time.sleep(0.01)
    # as the kernel may deliver a process-wide SIGTERM to one of Zenoh's threads
    signal.pthread_kill(threading.get_ident(), signal.SIGTERM)

try:
    threading.Thread(target=elsewhere, daemon=True).start()
    waiting.set()
    wait_for_stop()
except Shutdown:
    sys.exit(3)
"""


@pytest.mark.slow  # a real child process (no Zenoh), well under a second
def test_a_stop_signal_taken_by_another_thread_still_wakes_the_main_thread(
    tmp_path: Path,
) -> None:
    """signal.pause() in the main thread never returned when another thread took the signal
    (a router outlived its SIGKILLed launcher); wait_for_stop() wakes on it."""
    sup = Supervisor(tmp_path)
    child = sup.start("waiter", ["-c", SIGNAL_ON_ANOTHER_THREAD])
    try:
        assert child.proc.wait(WAIT_S) == 3, child.describe_exit()
    finally:
        sup.stop(grace_s=0.1)
