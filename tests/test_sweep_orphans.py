"""A killed sweep leaves no pool workers behind (they would take the cores from the next one)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _pool_workers(parent: int) -> set[int]:
    """The spawned pool workers whose parent is ``parent`` (read from /proc)."""
    found: set[int] = set()
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
            cmdline = (entry / "cmdline").read_bytes()
        except OSError:
            continue  # gone meanwhile
        ppid = int(stat.rsplit(")", 1)[1].split()[1])
        if ppid == parent and b"spawn_main" in cmdline:
            found.add(int(entry.name))
    return found


def _alive(pid: int) -> bool:
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return False
    return stat.rsplit(")", 1)[1].split()[0] != "Z"


@pytest.mark.slow
@pytest.mark.skipif(not Path("/proc").is_dir(), reason="reads the process table from /proc")
def test_killing_a_sweep_ends_its_pool_workers(tmp_path: Path) -> None:
    sweep = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "services.cli",
            "sweep",
            str(ROOT / "configs/experiments/smoke.toml"),
            "--jobs",
            "2",
            "--out",
            str(tmp_path / "sweep"),
        ],
        cwd=ROOT,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 60.0
        workers: set[int] = set()
        while len(workers) < 2 and time.monotonic() < deadline and sweep.poll() is None:
            workers |= _pool_workers(sweep.pid)
            time.sleep(0.05)
        assert len(workers) == 2, f"the sweep never started its two workers: {workers}"
        os.kill(sweep.pid, signal.SIGKILL)  # no chance to shut its pool down
        sweep.wait(timeout=10)
        deadline = time.monotonic() + 10.0
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.05)
        left = sorted(p for p in workers if _alive(p))
        assert left == [], f"pool workers {left} outlived their sweep by 10 s"
    finally:
        if sweep.poll() is None:
            sweep.kill()
            sweep.wait(timeout=10)
