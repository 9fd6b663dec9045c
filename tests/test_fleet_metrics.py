"""A fleet's safety metrics on synthetic truth records: two vehicles passing each other at a
chosen lateral offset, each with its own rho0, one maybe passing a circle; the deepest breach
is said in its own terms (the vehicle's rho0, or the larger of a pair's), and the run plot
marks when and where (the closest approach, each hull's nearest obstacle)."""

from __future__ import annotations

from typing import Any

import pytest
from helpers.launch_proc import REPO
from helpers.records import facts, ran

from common.config.loader import read_scenario_toml
from common.config.scenario import Scenario, scenario_from_raw
from common.messages import TruthState
from common.runtime.model.record import Record
from common.world.check import check_scenario
from services.launcher.plot import run_figure
from services.mission.fleet_metrics import closest_approach, fleet_metrics
from services.mission.outcome import describe
from services.mission.records import FleetMetrics
from services.mission.verdict import mission_failure

SPEED, DT = 1.5, 0.05  # m/s along x; the vehicles' truth period (s)
HULLS = 1.6  # two default hulls of radius 0.8 m: centre distance = hull-to-hull gap + HULLS


def _fleet(
    offset_m: float, rho0: tuple[float, float], circles: list[dict[str, float]] | None = None
) -> Scenario:
    """The head-on pair, auv2 on the line offset_m north of auv1's (its goal moved with it)."""
    raw = read_scenario_toml(REPO / "configs" / "fleet_headon.toml")
    raw["world"]["circles"] = circles or []
    one, two = raw["vehicles"]
    two["start"]["y_m"] = two["goal"]["y_m"] = 20.0 + offset_m
    one["planner"], two["planner"] = {"rho0_m": rho0[0]}, {"rho0_m": rho0[1]}
    return scenario_from_raw(raw, "pair.toml", check=check_scenario)


def _record(s: Scenario) -> Record:
    """Each vehicle straight from its start to its goal at SPEED, one truth state every DT."""
    rec = Record()
    for vid, m in s.members:
        x0, y0, x1 = m.world.start.x_m, m.world.start.y_m, m.world.goal.x_m
        heading = 1.0 if x1 > x0 else -1.0
        n = round(abs(x1 - x0) / (SPEED * DT)) + 1
        for i in range(n):
            rec.add(
                f"{vid}.vehicle",
                "truth",
                TruthState(
                    stamp=i * DT, source=f"{vid}.vehicle", seq=i + 1,
                    x=x0 + heading * SPEED * i * DT, y=y0, theta=0.0 if heading > 0 else 3.14159,
                    v=SPEED, w=0.0,
                ),
            )  # fmt: skip
    return rec


def _metrics(s: Scenario) -> FleetMetrics:
    return fleet_metrics(_record(s), s)


def test_a_pair_between_its_two_rho0_breaches_the_larger_and_is_named() -> None:
    m = _metrics(_fleet(1.2 + HULLS, (1.0, 1.5)))  # hull to hull 1.2 m: inside 1.5, not 1.0
    assert m.reached_goal and m.collisions == 0 and m.vehicle_collisions == 0
    assert m.min_separation_m == pytest.approx(1.2, abs=1e-3)
    assert m.outcome == "rho0_breach" and not m.success
    assert (m.rho0_breach_by, m.rho0_m) == ("auv1-auv2", 1.5)
    assert m.rho0_breach_m == pytest.approx(0.3, abs=1e-3)
    assert m.time_below_rho0_s > 0.0
    assert mission_failure(ran(m, end_reason="goal")) == (
        "mission failed: goal reached, but auv1 and auv2 came 0.30 m inside the safety "
        f"distance rho0 = 1.5 m of each other for {m.time_below_rho0_s:.1f} s "
        "(hull to hull 1.20 m)"
    )


def test_two_hulls_in_contact_are_named_with_how_deep() -> None:
    m = _metrics(_fleet(HULLS - 0.4, (1.0, 1.0)))  # hulls overlapping by 0.4 m, no obstacle
    assert m.outcome == "collision" and m.vehicle_collisions > 0 and m.collisions == 0
    # the pair and its depth, not an obstacle clearance an empty world does not have
    assert mission_failure(ran(m, end_reason="goal")) == (
        "mission failed: auv1 and auv2 in contact (hull to hull -0.40 m); goal reached"
    )


def test_a_pair_outside_both_rho0_is_a_success_that_names_no_one() -> None:
    m = _metrics(_fleet(1.2 + HULLS, (1.0, 1.0)))
    assert m.outcome == "success" and m.success
    assert (m.rho0_breach_m, m.rho0_breach_by, m.time_below_rho0_s) == (0.0, "", 0.0)
    assert m.rho0_m == 1.0
    # an empty world has no obstacle clearance to tell, a fleet its separation
    assert describe(m, facts()) == (
        f"goal reached in {m.travel_time_s:.2f} s, never inside the safety distance "
        "rho0 = 1.0 m (min separation 1.20 m)"
    )


def test_a_vehicles_breach_is_told_with_its_own_rho0_not_the_fleets_largest() -> None:
    # a circle of radius 2 m 3.5 m south of auv1's line: auv1's hull (0.8 m) passes 0.7 m from
    # it, 0.3 m inside auv1's rho0 of 1.0 m; auv2 passes 15 m away, its rho0 1.5 m
    s = _fleet(15.0, (1.0, 1.5), [{"id": 1, "x_m": 50.0, "y_m": 16.5, "radius_m": 2.0}])
    m = _metrics(s)
    one = m.vehicles["auv1"]
    assert m.outcome == "rho0_breach" and m.vehicles["auv2"].outcome == "success"
    assert (m.rho0_breach_by, m.rho0_m) == ("auv1", 1.0)
    assert m.rho0_breach_m == one.rho0_breach_m == pytest.approx(0.3, abs=1e-3)
    assert m.time_below_rho0_s == one.time_below_rho0_s > 0.0
    said = mission_failure(ran(m, end_reason="goal"))
    assert said == (
        "mission failed: goal reached, but auv1 came 0.30 m inside the safety distance "
        f"rho0 = 1.0 m for {one.time_below_rho0_s:.1f} s (min clearance 0.70 m)"
    )


def test_the_closest_approach_is_when_and_where_the_two_hulls_pass() -> None:
    # auv1 east from x = 10, auv2 west from x = 90, 2.0 m + HULLS apart: they pass at x = 50
    # after 40 m each at SPEED, t = 26.67 s (the nearest truth stamp of auv1's, DT apart)
    s = _fleet(2.0 + HULLS, (1.0, 1.0))
    rec = _record(s)
    near = closest_approach(rec, s)
    assert near is not None and (near.a, near.b) == ("auv1", "auv2")
    assert near.gap_m == pytest.approx(2.0, abs=1e-3)  # the nearest stamps pass 5 cm apart in x
    assert near.t_s == pytest.approx(40.0 / SPEED, abs=DT)
    assert near.a_xy[0] == pytest.approx(50.0, abs=SPEED * DT)
    assert near.b_xy[0] == pytest.approx(near.a_xy[0], abs=SPEED * DT)  # abreast
    assert near.b_xy[1] - near.a_xy[1] == pytest.approx(2.0 + HULLS)
    m = fleet_metrics(rec, s)
    assert m.min_separation_t_s == near.t_s and m.min_separation_m == near.gap_m


def test_a_fleet_plot_dots_every_track_in_time_and_marks_the_closest_approach() -> None:
    s = _fleet(2.0 + HULLS, (1.0, 1.0))
    rec = _record(s)
    fig = run_figure(rec, s)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.texts]
    assert labels == [f"auv1-auv2: 2.00 m hull to hull, t = {40.0 / SPEED:.1f} s"]
    # 80 m at SPEED: 53.3 s, so dots at 10 ... 50 s on each of the two tracks
    dots = [ln for ln in ax.lines if ln.get_marker() == "." and len(ln.get_xdata()) > 0]
    assert [len(ln.get_xdata()) for ln in dots] == [5, 5]
    assert sorted(dots[0].get_xdata()) == pytest.approx([10 + SPEED * t for t in range(10, 60, 10)])
    # open water: no vehicle came near an obstacle, so the legend explains no cross
    assert not [t for t in _legend(ax) if "nearest an obstacle" in t]


def test_one_vehicle_alone_has_no_closest_approach() -> None:
    s = _fleet(2.0 + HULLS, (1.0, 1.0))
    rec = Record()
    for key in ("auv1.vehicle",):
        for msg in _record(s).stream(key, "truth"):
            rec.add(key, "truth", msg)
    assert closest_approach(rec, s) is None
    assert fleet_metrics(rec, s).min_separation_t_s is None


def test_the_plot_says_where_a_vehicle_came_inside_its_rho0_of_an_obstacle() -> None:
    # the circle 3.5 m south of auv1's line at x = 50 (as above): auv1 0.70 m from it there,
    # 0.30 m inside its rho0, when it has run 40 m; auv2, 15 m north, keeps clear: no label
    s = _fleet(15.0, (1.0, 1.5), [{"id": 1, "x_m": 50.0, "y_m": 16.5, "radius_m": 2.0}])
    rec = _record(s)
    one = fleet_metrics(rec, s).vehicles["auv1"]
    assert one.min_clearance_t_s == pytest.approx(40.0 / SPEED, abs=DT)
    ax = run_figure(rec, s).axes[0]
    said = [t.get_text() for t in ax.texts if "obstacle" in t.get_text()]
    assert said == [
        f"auv1: 0.70 m from an obstacle, t = {one.min_clearance_t_s:.1f} s: 0.30 m inside rho0"
    ]
    crosses = [ln for ln in ax.lines if ln.get_marker() == "X" and len(ln.get_xdata()) > 0]
    assert len(crosses) == 2  # one per vehicle, auv1's rimmed red
    assert [t for t in _legend(ax) if "nearest an obstacle" in t] == [
        "nearest an obstacle (red rim: inside rho0)"
    ]
    assert [ln.get_markeredgecolor() for ln in crosses].count("tab:red") == 1


def _legend(ax: Any) -> list[str]:
    """The texts of the axes' legend (the run plot puts it below them)."""
    return [t.get_text() for t in ax.get_legend().get_texts()]


def test_a_single_vehicles_plot_always_says_how_near_it_came() -> None:
    s = scenario_from_raw(
        read_scenario_toml(REPO / "configs" / "default.toml"), "one.toml", check=check_scenario
    )
    rec = Record()
    for i in range(41):  # x = 5 .. 13 m on y = 20: the circle at (20, 20), radius 4, ahead
        rec.add("vehicle", "truth", TruthState(
            stamp=i * DT * 2, source="vehicle", seq=i + 1, x=5.0 + 0.2 * i, y=20.0, theta=0.0,
            v=2.0, w=0.0,
        ))  # fmt: skip
    gap = 20.0 - 4.0 - 13.0 - s.vehicle.radius_m  # the last state's hull to the circle
    ax = run_figure(rec, s).axes[0]
    assert [t.get_text() for t in ax.texts] == [
        f"{gap:.2f} m from an obstacle, t = {40 * DT * 2:.1f} s"
        + (f": {s.planner.rho0_m - gap:.2f} m inside rho0" if gap < s.planner.rho0_m else "")
    ]
