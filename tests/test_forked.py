"""Service processes forked from the pre-imported fork server (runtime.processes.forkserver)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.processes.children import fork, stop_all
from common.runtime.processes.forkserver import fork_module

REPO = Path(__file__).resolve().parents[1]

TESTS = Path(__file__).resolve().parent
ROOT = TESTS.parent


def _wait_for_line(log: Path, text: str, timeout_s: float = 30.0) -> None:
    """Poll a child's log file until `text` appears (the child is a separate process)."""
    deadline = time.monotonic() + timeout_s
    while text not in (log.read_text() if log.exists() else ""):
        assert time.monotonic() < deadline, f"{text!r} never appeared in {log}"
        time.sleep(0.01)


def test_a_forked_module_runs_main_with_its_argv_logs_and_exits_with_its_code(
    tmp_path: Path,
) -> None:
    log = tmp_path / "x.log"
    proc = fork_module("helpers.fork_target", ["exit", "3"], log)
    assert proc.wait(timeout=30) == 3
    assert proc.returncode == 3
    assert proc.poll() == 3
    text = log.read_text()
    assert "child argv ['exit', '3']" in text
    assert "to stderr" in text


def test_a_forked_process_reports_the_signal_that_ended_it(tmp_path: Path) -> None:
    child = fork("blocker", "helpers.fork_target", ["block"], tmp_path)
    _wait_for_line(tmp_path / "blocker.log", "child argv ['block']")  # now in signal.pause()
    assert child.proc.poll() is None
    child.signal(signal.SIGKILL)
    assert child.proc.wait(timeout=30) == -signal.SIGKILL
    assert "was killed by signal 9" in child.describe_exit()
    assert "child argv ['block']" in child.describe_exit()  # the log tail comes with it


def test_stop_all_ends_forked_services_politely(tmp_path: Path) -> None:
    children = [fork(f"b{i}", "helpers.fork_target", ["block"], tmp_path) for i in range(2)]
    for c in children:  # blocked, so the stop really meets a waiting service
        _wait_for_line(c.log_path, "child argv ['block']")
    stop_all(children, grace_s=5.0)
    # SIGINT ends signal.pause() with KeyboardInterrupt: a non-zero exit, not a kill
    assert all(c.proc.poll() not in (None, -signal.SIGKILL) for c in children)


def test_an_unguarded_main_script_is_not_run_again_in_the_children(tmp_path: Path) -> None:
    # multiprocessing would re-run the parent's script in each child; ours must not (a
    # script calling a lockstep run without `if __name__ == "__main__":` would break)
    script = tmp_path / "unguarded.py"
    log = tmp_path / "child.log"
    script.write_text(
        "from pathlib import Path\n"
        "from common.runtime.processes.forkserver import fork_module\n"
        "print('script top level', flush=True)\n"
        f"p = fork_module('helpers.fork_target', ['exit', '0'], Path({str(log)!r}))\n"
        "raise SystemExit(p.wait(timeout=30))\n"
    )
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), str(TESTS)]))
    out = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=60, env=env
    )
    assert out.returncode == 0, out.stderr
    assert out.stdout.count("script top level") == 1
    assert "script top level" not in log.read_text()
    assert "child argv ['exit', '0']" in log.read_text()


def test_a_daemonic_process_starts_its_services_by_spawning(tmp_path: Path) -> None:
    # Dask workers are daemonic, and multiprocessing forbids them children of their own: a
    # lockstep run there must still start its services (as fresh interpreters)
    import multiprocessing

    ctx = multiprocessing.get_context("spawn")
    result: multiprocessing.Queue[int] = ctx.Queue()
    proc = ctx.Process(target=_daemon_body, args=(str(tmp_path), result), daemon=True)
    proc.start()
    try:
        assert result.get(timeout=60) == 4
    finally:
        proc.join(timeout=30)
    assert "child argv ['exit', '4']" in (tmp_path / "from-daemon.log").read_text()


def _daemon_body(log_dir: str, result: object) -> None:
    from helpers.fork_target import fork_from_a_daemon

    # the spawned interpreter finds the helper module as an installed one would be found
    os.environ["PYTHONPATH"] = os.pathsep.join([str(ROOT), str(TESTS)])

    result.put(fork_from_a_daemon(log_dir))  # type: ignore[attr-defined]


def test_a_launch_preloads_only_what_its_missions_services_import() -> None:
    from common.runtime.model.mission import load_mission, preload
    from common.runtime.processes.forkserver import PRELOAD, RUNTIMES

    auv, _ = load_scenario(REPO / "configs" / "default.toml")
    assert preload(load_mission(auv)) == PRELOAD
    toy, _ = load_scenario(REPO / "configs" / "default.toml", ['run.mission="testloop"'])
    assert preload(load_mission(toy)) == (*RUNTIMES, "tests.helpers.testloop")


def test_the_fork_server_starts_under_a_temp_dir_too_long_for_its_socket(tmp_path: Path) -> None:
    # its socket goes in multiprocessing's pymp-* folder under the temp dir; from 80 bytes of
    # temp dir on, the path passed the 107 an AF_UNIX socket holds ("AF_UNIX path too long")
    deep = tmp_path / ("t" * max(1, 90 - len(str(tmp_path))))
    deep.mkdir()
    code = (
        "from common.runtime.processes.forkserver import fork_module, warm_up\n"
        "import pathlib, sys\n"
        "warm_up(())\n"
        f"log = pathlib.Path({str(deep / 'x.log')!r})\n"
        "p = fork_module('helpers.fork_target', ['exit', '3'], log)\n"
        "sys.exit(p.wait(60))\n"
    )
    env = {**os.environ, "TMPDIR": str(deep), "PYTHONPATH": f"{ROOT}{os.pathsep}{TESTS}"}
    res = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert res.returncode == 3, res.stderr  # the forked child's own exit code
