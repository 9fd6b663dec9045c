"""`tidelink launch` end to end: router and services as supervised processes over Zenoh.

Each test drives the real CLI in its own session and synchronises on the lines the launcher
prints (helpers/launch_proc.py), on pids.json and on process exits, always with timeouts.
The runtime self-test loop (tests.helpers.testloop) keeps most of these fast.
"""

from __future__ import annotations

import json
import math
import os
import signal
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers.launch_proc import (
    REPO,
    Tidelink,
    alive,
    judged_exit,
    kill_recorded,
    processes_mentioning,
    wait_dead,
)

from common.config.scenario import load_scenario
from common.messages import StateEstimate, TruthState, decode
from common.runtime.model.inproc import run_inproc
from common.runtime.processes.children import free_port
from common.runtime.run import write_outputs
from services.recording.reader import read_recording

pytestmark = pytest.mark.slow

WAIT_S = 45.0  # upper bound on any one wait; the happy paths take a few seconds
DIE_WITH_LAUNCHER_S = 10.0  # for a SIGKILLed launcher's processes to go (~1 s here)
TESTLOOP = """
[run]
mission = "testloop"
max_time_s = {max_time}
[runtime]
time_scale = {scale}
[run.mission_params]
crash_service = "{crash}"
crash_at_s = 1.0
"""


def _scenario(
    tmp_path: Path, *, max_time: float = 8.0, scale: float = 4.0, crash: str = ""
) -> Path:
    p = tmp_path / "scenario.toml"
    p.write_text(TESTLOOP.format(max_time=max_time, scale=scale, crash=crash))
    return p


def _metrics(out: Path) -> dict[str, Any]:
    return dict(json.loads((out / "metrics.json").read_text()))


def _pids(out: Path) -> dict[str, list[int]]:
    return dict(json.loads((out / "pids.json").read_text())["processes"])


def _inproc_keys(scenario: Path, tmp_path: Path, *overrides: str) -> set[str]:
    s, _ = load_scenario(scenario, list(overrides))
    return set(write_outputs(run_inproc(s), s, tmp_path / "inproc", wall_s=0.0).to_json())


@pytest.fixture
def out(tmp_path: Path) -> Any:
    d = tmp_path / "run"
    yield d
    kill_recorded(d / "pids.json")  # whatever a failing test left behind


def test_a_killed_service_is_restarted_and_rejoins_the_clock(tmp_path: Path, out: Path) -> None:
    scenario = _scenario(tmp_path, max_time=16.0)
    with Tidelink(
        "launch",
        str(scenario),
        "--out",
        str(out),
        "--restart",
        "filter=on-failure",
        "--backoff",
        "0.2",
    ) as t:
        t.wait_for(r"mission clock started", WAIT_S)
        t.wait_for(r"t=\s*[2-9]\.\d+ s of 16", WAIT_S)  # the loop runs; the plant is moving
        (first,) = _pids(out)["filter"]
        os.kill(first, signal.SIGKILL)
        t.wait_for(r"service 'filter' was killed by signal 9", WAIT_S)
        t.wait_for(r"restarting 'filter' in 0\.20 s \(restart 1 of 3\)", WAIT_S)
        joined = t.wait_for(r"service 'filter' rejoined at t=(\d+\.\d+) s", WAIT_S)
        assert t.wait(WAIT_S) == 0, t.stderr
    assert float(joined.group(1)) > 2.0
    assert len(_pids(out)["filter"]) == 2
    log = (out / "logs" / "filter.log").read_text()
    assert "joined the mission clock at t=" in log  # the new one started from the Tick's time
    m = _metrics(out)
    assert m["end_reason"] == "max_time" and m["runtime"] == "realtime"
    # without the filter's state the controller would push the plant on with a stale error;
    # with it back, the loop settles on the set-point (10) again
    assert m["final_error"] < 1.0
    assert set(m) == _inproc_keys(scenario, tmp_path)  # the same metrics as `tidelink run`
    assert (out / "run.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_restarted_vehicle_takes_up_where_its_hull_was(tmp_path: Path, out: Path) -> None:
    # the process is the vehicle's computer, not the vehicle: a restart must not teleport
    # the hull back to its start pose (it did: the estimate then ran ~20 m off, and one
    # chaos run in three ended in contact)
    scenario = REPO / "configs" / "default.toml"
    args = ("launch", str(scenario), "--time-scale", "4", "--set", "run.max_time_s=30")
    with Tidelink(
        *args, "--out", str(out), "--no-plot", "--record", "--restart", "vehicle=on-failure"
    ) as t:
        t.wait_for(r"t=\s*(?:[89]|1\d)\.\d+ s of 30", WAIT_S)  # under way, far from the start
        (first,) = _pids(out)["vehicle"]
        os.kill(first, signal.SIGKILL)
        t.wait_for(r"service 'vehicle' rejoined at t=", WAIT_S)
        assert t.wait(WAIT_S) == judged_exit(out), t.stderr
    assert (
        "vehicle: resumed the hull from its truth at t=" in (out / "logs/vehicle.log").read_text()
    )
    frames = read_recording(out / "run.mcap").frames
    truths = [
        m
        for f in frames
        if (f.service, f.stream) == ("vehicle", "truth")
        and isinstance(m := decode(f.payload), TruthState)
    ]
    # the restart: where the new process numbers its truths from 1 again
    (i,) = [k for k in range(1, len(truths)) if truths[k].seq < truths[k - 1].seq]
    last, resumed = truths[i - 1], truths[i]
    gap = resumed.stamp - last.stamp
    assert gap > 0.5 and math.hypot(last.x, last.y) > 8.0  # was under way when killed
    # no faster than it could move meanwhile; nowhere near the start pose
    assert math.hypot(resumed.x - last.x, resumed.y - last.y) <= 2.0 * gap + 0.1
    # the estimate: while the hull was unobserved it could run off by no more than the
    # distance it dead-reckoned meanwhile (a fixed bound fails when a loaded machine takes
    # longer to restart; the teleport it guards against put it ~20 m off), and once truths
    # flow again it converges back onto the hull
    tt, tx, ty = (np.array([getattr(s, k) for s in truths]) for k in ("stamp", "x", "y"))
    estimates = [
        m
        for f in frames
        if (f.service, f.stream) == ("estimator", "state")
        and isinstance(m := decode(f.payload), StateEstimate)
        and tt[0] <= m.stamp <= tt[-1]
    ]
    et = np.array([e.stamp for e in estimates])
    err = np.hypot(
        np.array([e.x for e in estimates]) - np.interp(et, tt, tx),
        np.array([e.y for e in estimates]) - np.interp(et, tt, ty),
    )
    assert err.max() <= 1.0 + last.v * gap, (err.max(), gap, last.v)
    assert err[et > resumed.stamp + 3.0].max() < 1.0, err[et > resumed.stamp + 3.0].max()
    assert _metrics(out)["collisions"] == 0


def test_a_crash_under_policy_never_fails_the_run_naming_the_service(
    tmp_path: Path, out: Path
) -> None:
    # 300 s of wall clock to max_time: ending within WAIT_S proves the run failed fast
    scenario = _scenario(tmp_path, max_time=600.0, crash="filter")
    with Tidelink("launch", str(scenario), "--out", str(out), "--no-plot") as t:
        assert t.wait(WAIT_S) == 1
    assert "service 'filter' exited with code 3 (restart policy 'never')" in t.stderr
    # what the run measured until the crash is written, the failure named
    m = json.loads((out / "metrics.json").read_text())
    assert m["end_reason"] == "service_failed", m
    assert m["failure"].startswith("service 'filter' exited with code 3"), m
    assert 0.0 < m["t_end_s"] < 600.0
    assert "mission failed at t=" in (out / "logs" / "launch.log").read_text()
    assert not [p for pids in _pids(out).values() for p in pids if alive(p)]
    # the others left on the run's stop Tick, not seconds later when its clock had gone
    for name in ("ctrl", "plant", "sensor"):
        assert "clock went away" not in (out / "logs" / f"{name}.log").read_text(), name


def test_on_failure_backs_off_doubling_then_gives_up(tmp_path: Path, out: Path) -> None:
    # the restarted filter joins after crash_at_s, so it crashes again at its first step
    scenario = _scenario(tmp_path, max_time=30.0, crash="filter")
    with Tidelink(
        "launch",
        str(scenario),
        "--out",
        str(out),
        "--no-plot",
        "--restart",
        "filter=on-failure:2",
        "--backoff",
        "0.2",
    ) as t:
        assert t.wait(WAIT_S) == 1
    err = t.stderr
    assert "restarting 'filter' in 0.20 s (restart 1 of 2)" in err
    assert "restarting 'filter' in 0.40 s (restart 2 of 2)" in err
    assert err.count("launch: service 'filter' exited with code 3") == 3
    assert "(gave up after 2 restarts)" in err
    assert len(_pids(out)["filter"]) == 3
    assert not [p for pids in _pids(out).values() for p in pids if alive(p)]


@pytest.mark.parametrize("when", ["starting", "running"])
def test_no_process_outlives_an_interrupted_launch(tmp_path: Path, out: Path, when: str) -> None:
    scenario = _scenario(tmp_path, max_time=100.0, scale=1.0)
    with Tidelink("launch", str(scenario), "--out", str(out), "--no-plot") as t:
        t.wait_for(r"router listening" if when == "starting" else r"mission clock started", WAIT_S)
        t.signal(signal.SIGINT)
        assert t.wait(WAIT_S) == 130, t.stderr
    pids = _pids(out)
    assert pids["router"] and (when == "starting" or len(pids) == 5)
    left = [p for ps in pids.values() for p in ps if alive(p)]
    assert left == [], f"still running after the launcher exited: {left}"
    assert processes_mentioning(str(out)) == []
    if when == "running":
        assert _metrics(out)["end_reason"] == "interrupted"


def test_no_process_outlives_a_sigkilled_launcher(tmp_path: Path, out: Path) -> None:
    """SIGKILL gives the launcher no chance to stop anything: its children go by themselves
    (the kernel's parent-death signal; the router used to listen on for good)."""
    scenario = _scenario(tmp_path, max_time=100.0, scale=1.0)
    with Tidelink("launch", str(scenario), "--out", str(out), "--no-plot") as t:
        t.wait_for(r"mission clock started", WAIT_S)
        t.signal(signal.SIGKILL)
        assert t.wait(WAIT_S) == -signal.SIGKILL
    names = {p: name for name, ps in _pids(out).items() for p in ps}
    assert len(names) == 5  # the router and four services
    # at once (each closes its session on SIGTERM), not after their own timeouts: a service
    # cut off from its router waits runtime.start_timeout_s (30 s) to rejoin it
    left = {names[p] for p in wait_dead(list(names), DIE_WITH_LAUNCHER_S)}
    assert not left, f"still running after the launcher was killed: {sorted(left)}"


def test_a_killed_router_fails_the_run_saying_it_is_never_restarted(
    tmp_path: Path, out: Path
) -> None:
    scenario = _scenario(tmp_path, max_time=100.0, scale=1.0)
    with Tidelink(
        "launch", str(scenario), "--out", str(out), "--no-plot", "--restart", "on-failure"
    ) as t:
        t.wait_for(r"mission clock started", WAIT_S)
        os.kill(_pids(out)["router"][0], signal.SIGKILL)
        assert t.wait(WAIT_S) == 1, t.stderr
    assert "the router is never restarted" in t.stderr
    m = _metrics(out)
    assert m["end_reason"] == "service_failed" and m["failure"], m


def test_a_killed_router_under_its_own_policy_is_restarted_and_the_run_goes_on(
    tmp_path: Path, out: Path
) -> None:
    """`--restart router=on-failure`: the router comes back on its endpoint, the same service
    processes reconnect to it and rejoin the clock, and the run ends with its own outcome."""
    scenario = _scenario(tmp_path, max_time=16.0)
    with Tidelink(
        "launch",
        str(scenario),
        "--out",
        str(out),
        "--restart",
        "router=on-failure",
        "--backoff",
        "0.2",
    ) as t:
        t.wait_for(r"mission clock started", WAIT_S)
        t.wait_for(r"t=\s*[2-9]\.\d+ s of 16", WAIT_S)  # mid-run, the loop running
        before = _pids(out)
        os.kill(before["router"][0], signal.SIGKILL)
        t.wait_for(r"service 'router' was killed by signal 9", WAIT_S)
        t.wait_for(r"restarted 'router' \(pid \d+, restart 1\)", WAIT_S)
        services = sorted(set(before) - {"router"})
        for name in services:  # each names itself once its session is back
            t.wait_for(rf"service '{name}' rejoined at t=", WAIT_S)
        assert t.wait(WAIT_S) == 0, t.stderr
    after = _pids(out)
    # one restart; a restarted router that fails to come up (seen once on a loaded fresh
    # clone) is restarted again by the same on-failure policy: one comes back, as asked
    assert len(after["router"]) >= 2
    # rejoined, not restarted: the same processes carried on
    assert {s: after[s] for s in services} == {s: before[s] for s in services}
    m = _metrics(out)
    assert m["end_reason"] == "max_time" and not m["failure"], m


def test_a_frozen_service_raises_an_alarm_and_counts_in_the_metrics(
    tmp_path: Path, out: Path
) -> None:
    """A SIGSTOPped service keeps its token and its connection; the launcher notices the
    silence (3 periods of nothing), says so, says when it speaks again, and the metrics
    hold how long it was overdue.

    Frozen once it runs: a service frozen before its first Tick has no clock yet, and on
    waking joins from the Ticks queued meanwhile (its first stamps can trail the launcher's
    by the seconds it was frozen), which is a late start, not this case."""
    scenario = _scenario(tmp_path, max_time=20.0)
    with Tidelink("launch", str(scenario), "--out", str(out), "--no-plot") as t:
        t.wait_for(r"mission clock started", WAIT_S)
        mark = 0
        # the progress lines come every 2 s of wall time: the one past t = 2 s comes when
        # every service has run on the clock for seconds
        while float(t.wait_for(r"t=\s*([0-9.]+) s of", WAIT_S, start=mark)[1]) < 2.0:
            mark = len(t.err)
        ctrl = _pids(out)["ctrl"][0]
        os.kill(ctrl, signal.SIGSTOP)
        try:
            since = float(t.wait_for(r"ALARM: ctrl unresponsive since t=([0-9.]+)", WAIT_S)[1])
            assert since > 0.0, "ctrl was frozen before it published anything"
            # stopped well past its limit on its own clock too (the services' clocks start
            # apart, so the launcher can call it silent a little before its own stamps show it)
            mark = len(t.err)
            while float(t.wait_for(r"t=\s*([0-9.]+) s of", WAIT_S, start=mark)[1]) < since + 4.5:
                mark = len(t.err)  # the next progress line (one every 2 s)
        finally:
            os.kill(ctrl, signal.SIGCONT)
        t.wait_for(r"ctrl responsive again at t=.* \(silent", WAIT_S)
        assert t.wait(WAIT_S) == 0, t.stderr
    m = _metrics(out)
    assert m["unresponsive_s"]["ctrl"] > 0.0, m["unresponsive_s"]
    assert m["unresponsive_s"]["plant"] == 0.0, m["unresponsive_s"]
    assert "ALARM: ctrl unresponsive" in (out / "logs" / "launch.log").read_text()


@pytest.mark.deterministic
def test_lockstep_launch_reproduces_inproc(testloop_toml: Path, tmp_path: Path, out: Path) -> None:
    ref = run_inproc(load_scenario(testloop_toml)[0])
    with Tidelink(
        "launch", str(testloop_toml), "--runtime", "lockstep", "--out", str(out), "--no-plot"
    ) as t:
        assert t.wait(WAIT_S) == 0, t.stderr
    m = _metrics(out)
    assert m["runtime"] == "lockstep"
    assert m["trajectory_sha256"] == ref.metrics.trajectory_sha256
    assert (m["t_end_s"], m["ticks"]) == (ref.t_end, ref.ticks)


def test_services_started_elsewhere_join_before_the_clock_starts(tmp_path: Path, out: Path) -> None:
    scenario = _scenario(tmp_path, max_time=8.0)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Tidelink(
        *("launch", str(scenario), "--out", str(out), "--no-plot", "--only", "ctrl,filter"),
        *("--listen", endpoint),
    ) as t:
        t.wait_for(r"waiting for plant, sensor to join", WAIT_S)
        assert "mission clock started" not in t.stderr
        with (
            Tidelink("service", "plant", str(scenario), "--connect", endpoint) as plant,
            Tidelink("service", "sensor", str(scenario), "--connect", endpoint) as sensor,
        ):
            t.wait_for(r"all 4 services alive", WAIT_S)
            t.wait_for(r"mission clock started", WAIT_S)
            assert t.wait(WAIT_S) == 0, t.stderr
            # remote services leave by themselves on the stop Tick
            assert plant.wait(WAIT_S) == 0 and sensor.wait(WAIT_S) == 0
    assert set(_pids(out)) == {"router", "ctrl", "filter"}
    assert _metrics(out)["final_error"] < 1.0
