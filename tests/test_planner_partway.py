"""A route no curve follows to the goal is planned part of the way (safety/partway.py)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from helpers.planner_world import default_scenario

from services.planner.decline import keeps_path_in_force
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D
from services.planner.safety.partway import PARTWAY_SHARES, plan_partway, route_point

SCENARIO = default_scenario()
ROUTE = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 40.0]])  # 70 m with one corner


def _request(r_min_m: float = 6.5) -> PlanRequest:
    return PlanRequest(
        start=Pose2D(x=0.0, y=0.0, theta=0.0),
        goal=Pose2D(x=30.0, y=40.0, theta=1.57),
        area=SCENARIO.world.area,
        obstacles=Obstacles(),
        vehicle_radius_m=SCENARIO.vehicle.radius_m,
        r_min_m=r_min_m,
        v_ref_mps=SCENARIO.vehicle.cruise_speed_mps,
        fix_goal_heading=True,
    )


FAILED = PlanResult(
    status="NO_PATH", reason="no feasible curve", strategy="no_curve", grid_path=ROUTE
)


def test_a_route_point_lies_on_the_route_at_its_arc_length() -> None:
    assert route_point(ROUTE, 0.0) == (0.0, 0.0)
    assert route_point(ROUTE, 15.0) == (15.0, 0.0)
    assert route_point(ROUTE, 30.0) == (30.0, 0.0)
    assert route_point(ROUTE, 50.0) == (30.0, 20.0)
    assert route_point(ROUTE, 1e3) == (30.0, 40.0)  # clamped to its ends
    assert route_point(ROUTE, -1.0) == (0.0, 0.0)


def test_partway_plans_to_a_point_along_the_route_heading_free_and_short_of_the_goal() -> None:
    asked: list[PlanRequest] = []

    def pipeline(q: PlanRequest) -> PlanResult:
        asked.append(q)
        return PlanResult(status="OK", reason="", strategy="searched", grid_path=ROUTE[:2])

    got = plan_partway(_request(), FAILED, pipeline)
    assert got is not None and got.ok and got.short_of_goal and got.partway
    assert len(asked) == 1 and not asked[0].fix_goal_heading
    assert (asked[0].goal.x, asked[0].goal.y) == route_point(ROUTE, PARTWAY_SHARES[0] * 70.0)
    assert got.reason.startswith(
        "no feasible curve; partway to (30.0, 5.0), 35 of the route's 70 m"
    )


def test_partway_tries_each_share_then_gives_up() -> None:
    asked: list[Pose2D] = []

    def nothing(q: PlanRequest) -> PlanResult:
        asked.append(q.goal)
        return PlanResult(status="NO_PATH", reason="no", strategy="no_curve")

    assert plan_partway(_request(), FAILED, nothing) is None
    assert len(asked) == len(PARTWAY_SHARES)
    # a share nearer the start than R_min along the route is not tried
    asked.clear()
    assert plan_partway(_request(r_min_m=25.0), FAILED, nothing) is None
    assert [(g.x, g.y) for g in asked] == [route_point(ROUTE, 35.0), route_point(ROUTE, 52.5)]
    assert (
        plan_partway(_request(), dataclasses.replace(FAILED, grid_path=ROUTE[:1]), nothing) is None
    )


@pytest.mark.parametrize("why", ["corridor", "cruise"])
def test_a_precaution_that_finds_only_a_partway_plan_keeps_the_path_in_force(why: str) -> None:
    partway = PlanResult(
        status="OK", reason="partway", strategy="partway", short_of_goal=True, partway=True
    )
    declined = keeps_path_in_force(why, partway, has_path=True, stepping_aside=False)
    assert declined is not None and "partway" in declined.detail
    # a path in force that has failed (or none) takes it: a receding-horizon step on
    assert keeps_path_in_force("infeasible", partway, has_path=True, stepping_aside=False) is None
    assert keeps_path_in_force(why, partway, has_path=False, stepping_aside=False) is None
