"""A plan's reason codes: each result names the strategy that made it and those rejected on the
way (services/planner/reasons.py), and its path message carries them to metrics and monitor."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from helpers.planner_world import circle, default_scenario, planner_core, polygon

from common.config.planner import PlannerConfig
from common.config.scenario import load_scenario
from common.messages import PathMsg, StateEstimate
from common.runtime.model.core import Delivery
from services.planner.path_message import path_message
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D, plan_path
from services.planner.reasons import STRATEGIES

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
CFG = PlannerConfig()
SCENARIO = default_scenario()
WORLD = SCENARIO.world
STATIC = Obstacles(circles=WORLD.circles, polygons=WORLD.polygons)
GOAL = Pose2D(x=95.0, y=20.0, theta=0.0)
COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))


def _plan(x: float, y: float, theta: float, obstacles: Obstacles = STATIC) -> PlanResult:
    req = PlanRequest(
        start=Pose2D(x=x, y=y, theta=theta),
        goal=GOAL,
        area=WORLD.area,
        obstacles=obstacles,
        vehicle_radius_m=SCENARIO.vehicle.radius_m,
        r_min_m=SCENARIO.vehicle.turn_radius_min_m,
        v_ref_mps=SCENARIO.vehicle.cruise_speed_mps,
    )
    return plan_path(req, CFG)


def test_an_ordinary_plan_is_searched_with_nothing_rejected() -> None:
    res = _plan(5.0, 20.0, 0.0)
    assert res.ok and res.strategy == "searched" and res.rejected == ()
    assert res.tried == ("searched",)


def test_a_heading_no_curve_leaves_along_turns_first_after_the_search() -> None:
    # hull 1.6 m from the polygon, heading at it (test_planner_escape.py): the search's curve
    # fails, a turn on an arc first makes the plan
    res = _plan(44.41, 19.72, 0.72)
    assert res.ok and "on a 6.0 m arc first" in res.reason
    assert (res.strategy, res.rejected) == ("turned_first", ("searched",))


def test_a_start_in_contact_escapes_first() -> None:
    res = _plan(15.5, 20.0, math.pi / 2)
    assert res.ok and (res.strategy, res.rejected) == ("escaped_first", ())


def test_out_of_the_area_heading_away_comes_about_after_the_way_out_fails() -> None:
    res = _plan(64.8, -0.7, -0.9)
    assert res.ok and "come about" in res.reason
    assert (res.strategy, res.rejected) == ("came_about_first", ("escaped_first",))


def test_a_no_path_says_why_and_what_ran_before() -> None:
    wall = polygon(((49.0, 0.0), (51.0, 0.0), (51.0, 40.0), (49.0, 40.0)))
    walled = _plan(5.0, 20.0, 0.0, Obstacles(polygons=(wall,)))
    assert walled.status == "NO_PATH" and "unreachable" in walled.reason
    assert (walled.strategy, walled.rejected) == ("no_route", ("searched",))
    assert walled.tried == ("searched",)  # a NO_PATH's code names no strategy run
    unsafe = _plan(5.0, 20.0, 0.0, Obstacles(circles=(circle(x=95.0, y=21.5, radius=1.0),)))
    assert (unsafe.strategy, unsafe.rejected) == ("goal_refused", ())
    # hull 1.03 m from circle 1, heading at it: every recovery ran, in order, and none helped
    stuck = _plan(17.0, 15.0, 0.5)
    assert stuck.status == "NO_PATH" and stuck.strategy == "no_curve"
    assert stuck.rejected == ("searched", "turned_first", "partway", "came_about_first")


@pytest.mark.parametrize("status", ["OK", "NO_PATH"])
def test_the_path_message_carries_the_codes(status: str) -> None:
    res = _plan(44.41, 19.72, 0.72) if status == "OK" else _plan(17.0, 15.0, 0.5)
    msg = path_message(res, stamp=1.0, path_id=3, status_since=1.0, why="no_path", v_ref=1.5)
    assert (msg.status, msg.strategy, msg.rejected) == (status, res.strategy, res.rejected)


def test_every_code_is_one_word_of_the_vocabulary() -> None:
    assert len(set(STRATEGIES)) == len(STRATEGIES)
    assert all(c.replace("_", "").isalpha() and c.islower() for c in STRATEGIES)


def test_the_planner_core_publishes_the_strategy_of_each_path() -> None:
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0", "world.start.x_m=15.5"])
    core = planner_core(s)
    est = StateEstimate(stamp=0.0, x=15.5, y=20.0, theta=1.5708, v=1.0, w=0.0, covariance=COV)
    core.deliver(Delivery(source="estimator", stream="state", msg=est, t=0.05))
    (path,) = [e.msg for e in core.step(0.05) if e.stream == "path"]
    assert isinstance(path, PathMsg) and path.status == "OK"
    assert core.last_result is not None
    assert path.strategy == core.last_result.strategy == "escaped_first"
