"""One forged record message cannot fake a run's result: during a real launch a client on the
router puts the vehicle's true state at the goal with seq 2**62 (as issue 14 found: the
launcher reported `goal` at once), with no source, as "vehicle" and as "planner". The run's
record refuses and counts every one, and the mission ends when the real vehicle arrives. (In
lockstep, where the trajectory must be inproc's bit for bit: tests/test_lockstep_adversaries.py.)"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from helpers.forged_truth import FORGED_SEQ, real_truth_due
from helpers.launch_proc import Tidelink, kill_recorded

from common.bus import Bus, Inbox, Keys
from common.config.bus import BusConfig
from common.messages import TruthState
from common.runtime.processes.children import free_port

pytestmark = pytest.mark.slow

WAIT_S = 120.0
SHORT = "configs/experiments/scenarios/short.toml"
SOURCES = ("", "vehicle", "planner")  # "" and "planner": wrong_source; "vehicle": seq_jump
EVERY = 100  # inject after every 100th real truth state (5 s of mission time)
LAST = 400  # ... up to seq 400 (t = 20 s), well before the real arrival (~27 s)


def _inject(endpoint: str, run: Tidelink) -> int:
    """Watch the real truth stream; after each EVERY-th state put one forgery per SOURCES on
    the vehicle's truth key. Returns how many rounds were put."""
    keys = Keys("short", "auv1")  # the short scenario's run and vehicle
    rounds = 0
    with Bus(BusConfig(mode="client", connect=(endpoint,)), keys) as bus:
        pub = bus.publisher_on(keys.stream("vehicle", "truth"))
        inbox = Inbox()
        bus.subscribe_stream("vehicle", "truth", inbox)
        while run.proc.poll() is None and rounds < LAST // EVERY:
            real = real_truth_due(inbox.get(timeout=1.0), EVERY)
            if real is None:
                continue
            for source in SOURCES:  # at the short scenario's goal, (36, 20)
                at_goal = dict(x=36.0, y=20.0, theta=0.0, v=0.0, w=0.0)
                pub.put(TruthState(stamp=real.stamp, source=source, seq=FORGED_SEQ, **at_goal))
            rounds += 1
    return rounds


def test_forged_truth_at_the_goal_is_refused_and_the_run_ends_for_real(tmp_path: Path) -> None:
    out = tmp_path / "run"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    launch = ["launch", SHORT, "--runtime", "realtime", "--listen", endpoint, "--no-plot"]
    try:
        with Tidelink(*launch, "--time-scale", "4", "--out", str(out)) as run:
            run.wait_for(r"mission clock started", WAIT_S)
            rounds = _inject(endpoint, run)
            assert run.wait(WAIT_S) == 0, run.stderr
    finally:
        kill_recorded(out / "pids.json")
    assert rounds == LAST // EVERY
    m = json.loads((out / "metrics.json").read_text())
    assert m["end_reason"] == "goal" and m["success"] is True, m
    assert m["record_rejected"] == {
        "wrong_source": 2 * rounds,
        "seq_jump": rounds,
        "conflict": 0,
        "future": 0,
    }
    assert "refused a message on vehicle/truth (seq_jump)" in run.stderr
    # the real vehicle's arrival, not a forged one at 5 s
    assert m["t_end_s"] > 25.0 and m["travel_time_s"] > 25.0
