"""A vehicle that starts in contact escapes and completes the mission (issue 14, defect 5).

`tidelink check` rejects such a start (tests/test_config.py); the scenario is loaded here
without that check, as a run would find itself after a fault (a coasting hold, a moving
obstacle), and run in process.
"""

from __future__ import annotations

import re
from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"


def test_a_start_in_contact_escapes_instead_of_deadlocking() -> None:
    # x = 15.5 puts the 0.8 m hull 0.3 m into circle 1 (20, 20, r 4), heading into it: the
    # planner answered NO_PATH every second and the vehicle sat in contact until max_time
    s, _ = load_scenario(DEFAULT, ["world.start.x_m=15.5", "run.max_time_s=120"])
    r = run_inproc(s)
    m = r.metrics
    assert r.reason == "goal" and m["reached_goal"] is True
    assert m["no_path_events"] == 0
    paths = r.record.stream("planner", "path")
    # the first plan waits for the first obstacle tracks (~0.65 s): it plans from an estimate
    # that has fused noisy fixes by then, so the hull clearance it finds is near, not at, -0.30
    assert re.search(r"start in contact \(hull clearance -0\.[234]\d m\)", paths[0].reason)  # type: ignore[attr-defined]
    truth = r.record.stream("vehicle", "truth")
    in_contact = [x.stamp for x in truth if x.collided]  # type: ignore[attr-defined]
    assert in_contact and in_contact[0] == 0.0
    # it turns on the spot and drives out within seconds, and never touches anything again
    assert max(in_contact) < 10.0
    assert len(in_contact) == round(max(in_contact) / s.vehicle.period_s) + 1
