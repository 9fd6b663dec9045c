"""A vehicle that starts in contact escapes and completes the mission (issue 14, defect 5).

`tidelink check` rejects such a start (tests/test_config.py); the scenario is loaded here
without that check, as a run would find itself after a fault (a coasting hold, a moving
obstacle), and run in process.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"


@pytest.mark.heavy
def test_a_start_in_contact_escapes_instead_of_deadlocking() -> None:
    # x = 15.5 puts the 0.8 m hull 0.3 m into circle 1 (20, 20, r 4), heading north along its
    # surface: the planner answered NO_PATH every second and the vehicle sat in contact until
    # max_time. Now it drives out forward on an arc away from the circle (no turn on the
    # spot: the plant turns no tighter than R_min, and not at all at rest)
    s, _ = load_scenario(
        DEFAULT, ["world.start.x_m=15.5", "world.start.theta_rad=1.5708", "run.max_time_s=120"]
    )
    r = run_inproc(s)
    m = r.metrics
    assert r.reason == "goal" and m.reached_goal is True
    assert m.no_path_events == 0
    paths = r.record.stream("planner", "path")
    # the first plan waits for the first obstacle tracks: it plans from an estimate that has
    # fused noisy fixes by then (and cannot yet tell their noise from a current's or a sway's
    # drift), so the hull clearance it finds is near, not at, -0.30: a way out either way
    # (a plan starts along the course over ground: at rest, the estimate's noise sets it off
    # the hull's heading, and the way out may then start with an arc that turns it first)
    first = paths[0]
    why = first.reason  # type: ignore[attr-defined]
    assert first.status == "OK", why  # type: ignore[attr-defined]
    assert first.strategy == "turned_first" or re.search(  # type: ignore[attr-defined]
        r"start (in contact|inside the safety margin) \(hull clearance -?0\.[0-4]\d m\)", why
    ), why
    truth = r.record.stream("vehicle", "truth")
    in_contact = [x.stamp for x in truth if x.collided]  # type: ignore[attr-defined]
    assert in_contact and in_contact[0] == 0.0
    # it drives out within seconds, never deeper, and never touches anything again
    assert max(in_contact) < 10.0
    assert len(in_contact) == round(max(in_contact) / s.vehicle.period_s) + 1
    assert m.min_clearance_m >= -0.3 - 1e-6
    assert m.max_executed_curvature <= 1.0 / s.vehicle.turn_radius_min_m + 1e-9


def test_a_start_in_contact_heading_into_the_obstacle_stays_put() -> None:
    # heading east, into circle 1: every forward way out first goes deeper, so the plan is
    # NO_PATH and the vehicle stays where it is rather than ram its way through (it used to
    # turn on the spot, which a rudder-steered vehicle cannot)
    s, _ = load_scenario(DEFAULT, ["world.start.x_m=15.5", "run.max_time_s=5"])
    r = run_inproc(s)
    m = r.metrics
    assert r.reason == "max_time" and m.reached_goal is False
    paths = r.record.stream("planner", "path")
    assert paths and all(p.status == "NO_PATH" for p in paths)  # type: ignore[attr-defined]
    # the hull clearance of the estimate the plan starts from (a noisy fix of the -0.30 m)
    why = paths[0].reason  # type: ignore[attr-defined]
    assert re.search(r"in contact with an obstacle \(hull clearance -0\.[2-4]\d m\)", why), why
    truth = r.record.stream("vehicle", "truth")
    assert max(q.v for q in truth) == 0.0  # type: ignore[attr-defined]
    assert m.min_clearance_m == pytest.approx(-0.3)
