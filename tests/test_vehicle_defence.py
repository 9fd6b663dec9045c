"""Defence in depth at the vehicle: a client on the router floods the command key with
well-formed commands (from the far future, and from another source) during a real realtime
launch; the vehicle applies none of them, counts them by reason, and reaches its goal."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from helpers.launch_proc import REPO, Tidelink, judged_exit, kill_recorded

from common.bus import Bus, Keys
from common.config.bus import BusConfig
from common.messages import VelocityCommand, encode_routing
from common.runtime.processes.children import free_port

pytestmark = pytest.mark.slow

WAIT_S = 60.0
SMALL = REPO / "configs" / "experiments" / "scenarios" / "small.toml"


def test_a_flood_of_hostile_commands_is_rejected_by_reason_and_the_mission_ends_well(
    tmp_path: Path,
) -> None:
    out = tmp_path / "run"
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    # the small smoke mission (~35 s to its goal): what is defended is the same vehicle
    launch = ["launch", str(SMALL), "--listen", endpoint, "--time-scale", "8"]
    try:
        with Tidelink(*launch, "--out", str(out), "--no-plot") as run:
            run.wait_for(r"mission clock started", WAIT_S)
            keys = Keys("small", "auv1")  # the small scenario's run and vehicle
            cfg = BusConfig(mode="client", connect=(endpoint,))
            # routing that delivers at once to the vehicle: what a crafted client could send
            routing = encode_routing(0, {"vehicle": (0,)})
            sent = 0
            with Bus(cfg, keys) as bus:
                pub = bus.publisher_on(keys.stream("planner", "cmd"))
                while run.proc.poll() is None and sent < 1000:
                    # the planner's name in the envelope, stamped 10^6 s ahead (issue 14, 1)
                    future = VelocityCommand(
                        stamp=1.0e6, v=2.0, w=0.5, path_id=1, source="planner", seq=10**9
                    )
                    # a fresh-looking command from someone else
                    other = VelocityCommand(stamp=0.0, v=2.0, w=0.5, path_id=1, source="monitor")
                    pub.put(future, attachment=routing)
                    pub.put(other, attachment=routing)
                    sent += 2
                    time.sleep(0.01)  # pacing a 100 Hz flood, not a wait for a result
            # the mission's judgement (the safety distance) is asserted below by what matters
            # here: the goal reached without contact
            assert run.wait(WAIT_S) == judged_exit(out), run.stderr
    finally:
        kill_recorded(out / "pids.json")
    m = json.loads((out / "metrics.json").read_text())
    assert m["end_reason"] == "goal" and m["collisions"] == 0, m
    by_reason = m["commands_rejected_by_reason"]
    assert by_reason["future"] > 0 and by_reason["wrong_source"] > 0, by_reason
    assert by_reason["out_of_order"] == 0  # nothing locked the order check
    log = (out / "logs" / "vehicle.log").read_text()
    assert "rejected a command (future)" in log and "rejected a command (wrong_source)" in log
