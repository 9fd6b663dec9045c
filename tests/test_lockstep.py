"""Lockstep over real Zenoh and separate processes reproduces inproc bit for bit."""

from __future__ import annotations

import multiprocessing
import tempfile
import time
from pathlib import Path

import pytest

from common.config.scenario import load_scenario
from common.messages import LinkStats
from common.runtime.distributed.lockstep import run_lockstep
from common.runtime.distributed.loop_times import PHASES
from common.runtime.distributed.realtime_driver import run_realtime
from common.runtime.model.inproc import run_inproc
from common.runtime.processes.supervisor import ServiceFailed

pytestmark = pytest.mark.slow


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_lockstep_equals_inproc_under_a_lossy_network(
    testloop_toml: Path, tmp_path: Path, seed: int
) -> None:
    s, raw = load_scenario(testloop_toml, seed=seed)
    ref = run_inproc(s)
    got = run_lockstep(s, raw, tmp_path / "logs")
    assert got.metrics.trajectory_sha256 == ref.metrics.trajectory_sha256
    assert got.metrics == ref.metrics
    assert (got.reason, got.t_end, got.ticks) == (ref.reason, ref.t_end, ref.ticks)
    # every stream, every message: identical (stats included)
    assert got.record.keys() == ref.record.keys()
    for key in ref.record.keys():
        assert got.record.stream(*key) == ref.record.stream(*key)


def _hog(stop_at: float) -> None:
    while time.monotonic() < stop_at:
        pass


@pytest.mark.deterministic  # the point: no load changes a lockstep run, its hogs' included
def test_lockstep_is_deterministic_under_cpu_load(testloop_toml: Path, tmp_path: Path) -> None:
    s, raw = load_scenario(testloop_toml)
    first = run_lockstep(s, raw, tmp_path / "a")
    # one hog: with the run's five processes, more than the two cores can serve at once
    hogs = [multiprocessing.Process(target=_hog, args=(time.monotonic() + 60,))]
    for h in hogs:
        h.start()
    try:
        second = run_lockstep(s, raw, tmp_path / "b")
    finally:
        for h in hogs:
            h.terminate()
            h.join()
    assert second.metrics.trajectory_sha256 == first.metrics.trajectory_sha256


def test_a_dead_service_fails_lockstep_fast_and_names_it(
    testloop_toml: Path, tmp_path: Path
) -> None:
    s, raw = load_scenario(
        testloop_toml,
        overrides=[
            'run.mission_params.crash_service="filter"',
            "run.mission_params.crash_at_s=2.0",
        ],
    )
    # the message proves the exit itself was detected (a tick timeout says "timed out")
    with pytest.raises(ServiceFailed, match=r"service 'filter' exited with code 3"):
        run_lockstep(s, raw, tmp_path / "logs")


def test_a_run_without_a_log_folder_leaves_nothing_behind_unless_it_fails(
    testloop_toml: Path,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    caplog: pytest.LogCaptureFixture,
) -> None:
    temp = tmp_path / "temp"  # where the run's temporary folders go
    temp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(temp))
    s, raw = load_scenario(testloop_toml, overrides=["run.max_time_s=3.0"])
    assert run_lockstep(s, raw).reason == "max_time"
    assert list(temp.glob("tidelink-*")) == []  # (multiprocessing keeps its pymp-*)
    crashing = [
        'run.mission_params.crash_service="filter"',
        "run.mission_params.crash_at_s=1.0",
    ]
    s, raw = load_scenario(testloop_toml, overrides=crashing)
    with pytest.raises(ServiceFailed, match=r"service 'filter' exited with code 3"):
        run_lockstep(s, raw)
    # the failure's evidence stays, and the log says where
    (kept,) = temp.glob("tidelink-*")
    assert (kept / "filter.log").is_file() and str(kept) in caplog.text


def test_realtime_runs_the_same_cores(testloop_toml: Path, tmp_path: Path) -> None:
    s, raw = load_scenario(testloop_toml, overrides=["runtime.time_scale=5"])
    r = run_realtime(s, raw, tmp_path / "logs")
    assert r.reason == "max_time"
    assert r.metrics.final_error < 1.0  # same loop, wall-clock timing: converges as well
    assert {k for k, _ in r.record.keys()} >= {"ctrl", "filter", "plant", "sensor"}
    logs = {p.stem for p in (tmp_path / "logs").glob("*.log")}
    assert logs == {"ctrl", "filter", "plant", "sensor"}
    # each service's statistics say where its loop's time went (loop_times.py), in order
    for name in ("ctrl", "filter", "plant", "sensor"):
        stats = [m for m in r.record.stream(name, "stats") if isinstance(m, LinkStats)]
        c = stats[-1].counters
        for phase in PHASES:
            p50, p95, top = (c[f"loop.{phase}_{q}_us"] for q in ("p50", "p95", "max"))
            assert 0 <= p50 <= p95 <= top, (name, phase, c)
        assert 0 < c["loop.step_p50_us"] < 1_000_000, (name, c)  # a toy core steps in < 1 s


def test_lockstep_equals_inproc_with_event_driven_cores(
    testloop_toml: Path, tmp_path: Path
) -> None:
    """Wake inputs: time advances to each modelled delivery, not only to periodic steps."""
    s, raw = load_scenario(testloop_toml, overrides=["run.mission_params.event_driven=true"])
    ref = run_inproc(s)
    got = run_lockstep(s, raw, tmp_path / "logs")
    assert got.metrics.trajectory_sha256 == ref.metrics.trajectory_sha256
    assert got.ticks == ref.ticks
    periodic = run_inproc(load_scenario(testloop_toml)[0])
    assert ref.ticks > periodic.ticks  # deliveries really were events of their own
