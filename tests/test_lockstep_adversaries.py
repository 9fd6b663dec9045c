"""A lockstep launch with three adversaries on its bus changes nothing: bit for bit inproc's run.

During one real lockstep launch of the short mission (router, clock, four service processes):
- a client puts, every 5 ms, a message that is no ack on the planner's ack key, and an ack
  that claims to be the vehicle's (the coordinator counts an ack on its service's own key
  only);
- after every EVERY-th real true state it puts the vehicle's true state at the goal with
  seq 2**62, with no source, as "vehicle" and as "planner" (issue 14: the launcher reported
  `goal` at once): the run's record refuses and counts every one;
- a `tidelink monitor` joins, then is SIGSTOPped for the rest of the run (its socket fills,
  the watch tap drops its copies).
The mission ends when the real vehicle arrives, and its trajectory is the inproc run's.
"""

from __future__ import annotations

import json
import signal
from dataclasses import dataclass
from pathlib import Path

import pytest
from helpers.forged_truth import FORGED_SEQ, real_truth_due
from helpers.launch_proc import REPO, Tidelink, kill_recorded
from helpers.runs import inproc

from common.bus import Bus, Inbox, Keys
from common.config.bus import BusConfig
from common.config.scenario import load_scenario
from common.messages import TickAck, TruthState
from common.runtime.processes.children import free_port

pytestmark = [pytest.mark.slow, pytest.mark.deterministic]

WAIT_S = 120.0
SHORT = REPO / "configs" / "experiments" / "scenarios" / "short.toml"
SOURCES = ("", "vehicle", "planner")  # "" and "planner": wrong_source; "vehicle": seq_jump
EVERY = 100  # forged truth after every 100th real one (5 s of mission time) ...
LAST = 400  # ... up to seq 400 (t = 20 s), well before the real arrival (~27 s)
AT_GOAL = dict(x=36.0, y=20.0, theta=0.0, v=0.0, w=0.0)  # the short scenario's goal


@dataclass
class Forged:
    acks: int = 0  # pairs of forged acks put
    truth_rounds: int = 0  # rounds of forged true states put


def _forge(endpoint: str, run: Tidelink) -> Forged:
    """Put forged acks every 5 ms and forged true states after every EVERY-th real one, while
    the run lasts."""
    keys = Keys("short", "auv1")  # the short scenario's run and vehicle
    done = Forged()
    not_an_ack = dict(x=0.0, y=0.0, theta=0.0, v=0.0, w=0.0)
    with Bus(BusConfig(mode="client", connect=(endpoint,)), keys) as bus:
        acks = bus.publisher_on(keys.ack("planner"))
        truth = bus.publisher_on(keys.stream("vehicle", "truth"))
        inbox = Inbox()
        # the real truth travels in the vehicle's acks, not on its stream key: the forger
        # paces itself on the watch tap's copy of it
        bus.subscribe(keys.watch("vehicle", "truth"), inbox)
        while run.proc.poll() is None:
            acks.put(TruthState(stamp=1.0, source="planner", seq=done.acks + 1, **not_an_ack))
            acks.put(TickAck(stamp=1.0, tick=done.acks, service="vehicle", next_us=0, wakes={}))
            done.acks += 1
            real = real_truth_due(inbox.get(timeout=0.005), EVERY)
            if real is None:
                continue
            if done.truth_rounds < LAST // EVERY:
                for source in SOURCES:
                    truth.put(
                        TruthState(stamp=real.stamp, source=source, seq=FORGED_SEQ, **AT_GOAL)
                    )
                done.truth_rounds += 1
    return done


def test_forged_acks_forged_truth_and_a_frozen_monitor_change_nothing(tmp_path: Path) -> None:
    out = tmp_path / "run"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    launch = ["launch", str(SHORT), "--runtime", "lockstep", "--listen", endpoint, "--no-plot"]
    try:
        with Tidelink(*launch, "--out", str(out)) as run:
            run.wait_for(r"router listening", WAIT_S)
            with Tidelink("monitor", "--connect", endpoint, "--json", "--every", "0.1") as mon:
                mon.wait_for(r'"event": "joined"', WAIT_S, stdout=True)
                mon.signal(signal.SIGSTOP)
                try:
                    run.wait_for(r"mission clock started", WAIT_S)
                    forged = _forge(endpoint, run)
                    assert run.wait(WAIT_S) == 0, run.stderr
                finally:
                    mon.signal(signal.SIGCONT)
    finally:
        kill_recorded(out / "pids.json")
    assert forged.acks > 100 and forged.truth_rounds == LAST // EVERY, forged
    m = json.loads((out / "metrics.json").read_text())
    assert m["end_reason"] == "goal" and m["success"] is True, m
    rounds = forged.truth_rounds
    assert m["record_rejected"] == {
        "wrong_source": 2 * rounds,
        "seq_jump": rounds,
        "conflict": 0,
        "future": 0,
    }
    assert "refused a message on vehicle/truth (seq_jump)" in run.stderr
    ref = inproc(load_scenario(SHORT)[0])  # the whole run, exactly as if nobody had interfered
    assert m["trajectory_sha256"] == ref.metrics.trajectory_sha256
    assert m["t_end_s"] == ref.t_end
