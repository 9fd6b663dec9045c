"""The planner service core: commands, the stale-estimate guard and the NO_PATH stop."""

from __future__ import annotations

import copy
import dataclasses
import logging
import math
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
from helpers.planner_world import planner_core

from common.config.scenario import load_scenario
from common.messages import ObstacleTracks, PathMsg, StateEstimate, Track, VelocityCommand
from common.runtime.deferred import AtOnce
from common.runtime.model.core import Delivery, Emit
from services.planner import plan as plan_module
from services.planner.core import PlannerCore
from services.planner.decline import PRECAUTIONS
from services.planner.reasons import PLANS_DECLINED
from services.planner.replan import ReplanDecision, ReplanReason
from services.planner.result import PlanResult, Pose2D

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))
COV6 = tuple(0.01 if i % 7 == 0 else 0.0 for i in range(36))


def _core(overrides: list[str] | None = None, *, wait_for_tracks: bool = False) -> PlannerCore:
    """The default scenario's planner; most tests here are about planning, not about the first
    plan's wait for the obstacle tracks (tested on its own below), so they switch it off."""
    wait = [] if wait_for_tracks else ["planner.first_plan_wait_s=0"]
    s, _ = load_scenario(DEFAULT, [*wait, *(overrides or [])])
    return planner_core(s)


def _estimate(stamp: float, x: float = 5.0, y: float = 20.0, v: float = 1.0) -> Delivery:
    est = StateEstimate(stamp=stamp, x=x, y=y, theta=0.0, v=v, w=0.0, covariance=COV)
    return Delivery(source="estimator", stream="state", msg=est, t=stamp + 0.05)


def test_plans_then_commands_within_the_bounds() -> None:
    core = _core()
    core.deliver(_estimate(0.0))
    out = core.step(0.05)
    path = [e.msg for e in out if e.stream == "path"]
    cmds = [e.msg for e in out if e.stream == "cmd"]
    assert len(path) == 1 and isinstance(path[0], PathMsg) and path[0].status == "OK"
    assert len(cmds) == 1 and isinstance(cmds[0], VelocityCommand)
    assert 0.0 < cmds[0].v <= core.vehicle.v_max_mps  # eq. (11)
    assert core.vehicle.w_min_rps <= cmds[0].w <= core.vehicle.w_max_rps


def test_no_command_from_a_stale_estimate() -> None:
    core = _core()
    core.deliver(_estimate(0.0))
    assert [e for e in core.step(0.05) if e.stream == "cmd"]
    # the uplink goes quiet: past max_estimate_age_s the planner stops commanding
    assert [e for e in core.step(0.9) if e.stream == "cmd"]
    assert core.step(1.2) == []
    assert core.stale_skips == 1
    core.deliver(_estimate(1.25, x=6.8))  # the link is back
    assert [e for e in core.step(1.3) if e.stream == "cmd"]


def test_walled_off_goal_stops_the_vehicle_and_says_why() -> None:
    wall = [
        "world.polygons=[{id = 20, vertices_m = [60.0, 0.0, 62.0, 0.0, 62.0, 40.0, 60.0, 40.0]}]"
    ]
    core = _core(wall)
    core.deliver(_estimate(0.0))
    out = core.step(0.05)
    (path,) = [e.msg for e in out if e.stream == "path"]
    assert isinstance(path, PathMsg)
    assert path.status == "NO_PATH" and path.reason
    (cmd,) = [e.msg for e in out if e.stream == "cmd"]
    assert isinstance(cmd, VelocityCommand)
    assert (cmd.v, cmd.w) == (0.0, 0.0)


def test_a_start_in_contact_drives_out_on_an_arc() -> None:
    # issue 14 defect 5: x = 15.5 puts the hull 0.3 m into circle 1 (the planner used to
    # answer NO_PATH with v = 0 forever). Heading north, along its surface, the way out is
    # an arc to the left, away from it: the vehicle follows it at once, forward, as the
    # plant allows (no turn on the spot, |w| <= v / R_min)
    core = _core(["world.start.x_m=15.5"])
    est = StateEstimate(stamp=0.0, x=15.5, y=20.0, theta=1.5708, v=1.0, w=0.0, covariance=COV)
    core.deliver(Delivery(source="estimator", stream="state", msg=est, t=0.05))
    out = core.step(0.05)
    (path,) = [e.msg for e in out if e.stream == "path"]
    (cmd,) = [e.msg for e in out if e.stream == "cmd"]
    assert isinstance(path, PathMsg) and isinstance(cmd, VelocityCommand)
    assert path.status == "OK" and "start in contact (hull clearance -0.30 m)" in path.reason
    assert core.last_result is not None and core.last_result.turn_rad > 0.0
    # the profile ramps from the vehicle's speed: 1 m/s 50 ms ago, braking since (no command
    # has reached it yet)
    assert cmd.v == pytest.approx(1.0 - 0.05 * 0.3, abs=1e-3)
    assert 0.0 < cmd.w <= 1.0 / core.vehicle.turn_radius_min_m  # left, within R_min at 1 m/s
    # along the way out, no replan (it passes closer than rho0 by design; the replan policy
    # must not call that infeasible)
    curve = core.last_result.curve()
    for u in (0.005, 0.01, 0.02):
        x, y = (float(c) for c in curve.evaluate(np.array([u]), 0)[0, 0])
        assert not core.policy.check(
            1.0, Pose2D(x=x, y=y, theta=1.7), core.goal, core.seen.at(1.0)
        ).replan


def test_a_start_in_contact_heading_into_the_obstacle_stops_and_says_why() -> None:
    # heading east, into circle 1: every forward way out first goes deeper (no reverse, no
    # turn on the spot): NO_PATH, and the vehicle is told to stop where it is
    core = _core(["world.start.x_m=15.5"])
    core.deliver(_estimate(0.0, x=15.5))
    out = core.step(0.05)
    (path,) = [e.msg for e in out if e.stream == "path"]
    (cmd,) = [e.msg for e in out if e.stream == "cmd"]
    assert isinstance(path, PathMsg) and isinstance(cmd, VelocityCommand)
    assert path.status == "NO_PATH" and "in contact with an obstacle" in path.reason
    assert (cmd.v, cmd.w) == (0.0, 0.0)


def test_every_path_says_since_when_its_status_has_held(monkeypatch: pytest.MonkeyPatch) -> None:
    # the launcher raises its NO_PATH alarm from PathMsg.stamp - PathMsg.status_since; with
    # the goal occupied the planner would go part of the way (partway.py), not what is tested
    monkeypatch.setattr(plan_module, "plan_partway", lambda *a: None)
    core = _core()

    def path_at(t: float, blocked: bool) -> PathMsg:
        # a tracked obstacle parked on the goal walls it off while it is there
        parked = Track(
            id=50, x=95.0, y=20.0, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=6.0, covariance=COV6
        )
        tracks = ObstacleTracks(stamp=t - 0.05, tracks=(parked,) if blocked else ())
        core.deliver(Delivery(source="estimator", stream="tracks", msg=tracks, t=t))
        core.deliver(_estimate(t - 0.05))
        (path,) = [e.msg for e in core.step(t) if e.stream == "path"]
        assert isinstance(path, PathMsg)
        return path

    # NO_PATH, replanned every min_replan_interval_s, keeps the time it began
    first = path_at(0.1, blocked=True)
    again = path_at(1.2, blocked=True)
    assert (first.status, first.status_since) == ("NO_PATH", 0.1)
    assert (again.status, again.status_since, again.stamp) == ("NO_PATH", 0.1, 1.2)
    ok = path_at(2.3, blocked=False)
    assert (ok.status, ok.status_since) == ("OK", 2.3)


# --- losing the planner for seconds (issue 14, defect 4) ----------------------------------------


def _along(stamp: float) -> Delivery:
    """The estimate of a vehicle running east at 1.5 m/s on y = 14 (between circles 1 and 2)."""
    return _estimate(stamp, x=5.0 + 1.5 * stamp, y=14.0)


def _cmds(out: list[Emit]) -> list[VelocityCommand]:
    return [e.msg for e in out if isinstance(e.msg, VelocityCommand)]


def _paths(out: list[Emit]) -> list[PathMsg]:
    return [e.msg for e in out if isinstance(e.msg, PathMsg)]


@pytest.mark.parametrize("horizon_s", [0.0, 3.0], ids=["single commands", "sequences"])
@pytest.mark.parametrize("stepped_in_the_gap", [True, False], ids=["uplink out", "SIGSTOP"])
@pytest.mark.parametrize("backlog_order", [1, -1], ids=["backlog in order", "backlog reversed"])
def test_after_a_gap_the_first_command_is_planned_from_the_newest_estimate(
    stepped_in_the_gap: bool, backlog_order: int, horizon_s: float
) -> None:
    # the estimates arrive 50 ms after their stamp: staleness is age beyond that, > 0.95 s
    setup = ["world.start.y_m=14.0", "planner.max_estimate_age_s=0.95"]
    # (a horizon this short has no room for the stop tail: sequence.py)
    setup += [f"controller.sequence.horizon_s={horizon_s}", "controller.sequence.stop_tail=false"]
    # the rollout's cushion without the estimate's std (0.1 m here): the path between circles
    # 1 and 2 is flown 1.16 m from them, and made again wider for it (its reason says so)
    setup += ["planner.tuning.rollout_start_sigmas=0.0"]
    core = _core(setup)
    k = 0
    for k in range(100):  # 10 s of normal operation at 10 Hz
        t = 0.05 + 0.1 * k
        core.deliver(_along(t - 0.05))
        assert _cmds(core.step(t))
    last = 0.05 + 0.1 * k
    # 8 s without estimates: the planner either keeps stepping without fresh input (its
    # uplink is out) or does not step at all (SIGSTOP: the realtime loop skips the periods);
    # 8 s is beyond what the vehicle runs on blind (its buffer of horizon_s, then hold_after_s),
    # and the last command's buffer ran out more than the 1.5 s before the newest estimate
    # that the planner looks back at the commands for the yaw rate (command/link.py)
    assert core.resume_after_s == horizon_s + core.vehicle.watchdog.hold_after_s < 8.0
    if stepped_in_the_gap:
        for j in range(1, 81):
            cmds = _cmds(core.step(last + 0.1 * j))
            # commands from the last estimate while it is fresh, then none: the vehicle holds
            assert bool(cmds) is (0.1 * j <= core.cfg.max_estimate_age_s)
        assert core.stale_skips == 71
    t_wake = last + 8.1
    # it wakes with the 8 s backlog of estimates, delivered before its next step
    backlog = [round(last + 0.1 * j, 9) for j in range(1, 81)]
    for stamp in backlog[::backlog_order]:
        core.deliver(_along(stamp))
    out = core.step(t_wake)
    newest = max(backlog)
    assert core.inputs.state is not None and core.inputs.state.stamp == newest
    (path,) = _paths(out)
    assert (path.status, path.reason) == ("OK", "resumed")
    # the new path starts at the newest estimate, not where the old plan left off; with
    # sequences, where the vehicle will be when it takes effect: the estimate carried the
    # 0.1 s to now, braking at 0.3 m/s^2 from its 1 m/s under HOLD, 0.0985 m further east
    ahead = 0.0985 if horizon_s else 0.0
    assert path.control_points[:2] == pytest.approx((5.0 + 1.5 * newest + ahead, 14.0), abs=1e-3)
    # and the command is what a planner that knew only that estimate would send (to float
    # noise with sequences: the two predictions pass through different schedules' cuts)
    fresh = _core(setup)
    fresh.deliver(_along(newest))
    (expected,) = _cmds(fresh.step(t_wake))
    (cmd,) = _cmds(out)
    assert (cmd.v, cmd.w) == pytest.approx((expected.v, expected.w), abs=1e-12)
    assert cmd.v_next == pytest.approx(expected.v_next, abs=1e-3)  # quantised: one unit
    assert cmd.w_next == pytest.approx(expected.w_next, abs=1e-3)
    assert len(cmd.v_next) == round(horizon_s / core.cfg.period_s)


def test_a_restarted_planner_plans_from_the_estimate_not_from_the_scenario_start() -> None:
    core = _core()  # a new process: no state, the scenario says start (5, 20)
    assert core.step(40.0) == []  # nothing to plan from until an estimate comes
    core.deliver(_estimate(40.0, x=30.0, y=14.0))
    (path,) = _paths(core.step(40.05))
    # from the estimate carried the 50 ms to now (heading east at 1 m/s)
    assert path.control_points[:2] == pytest.approx((30.05, 14.0), abs=2e-3)


def test_an_estimate_from_the_future_cannot_hold_the_place_of_later_ones() -> None:
    core = _core()
    core.deliver(_estimate(1.0))
    bogus = StateEstimate(stamp=1e6, x=50.0, y=5.0, theta=0.0, v=1.0, w=0.0, covariance=COV)
    core.deliver(Delivery(source="estimator", stream="state", msg=bogus, t=1.05))
    assert core.inputs_rejected == {"state.future": 1}
    core.deliver(_estimate(1.1, x=6.5))
    core.deliver(_estimate(0.9, x=4.0))  # late and older: not taken over the newer one
    state = core.inputs.state
    assert state is not None and (state.stamp, state.x) == (1.1, 6.5)


# --- the first plan waits for the first obstacle tracks (issue 15, finding 5) ---------------


def _tracks(stamp: float, *tracks: Track) -> Delivery:
    msg = ObstacleTracks(stamp=stamp, tracks=tracks)
    return Delivery(source="estimator", stream="tracks", msg=msg, t=stamp + 0.05)


def test_the_first_plan_waits_for_tracks_then_sees_the_moving_obstacle() -> None:
    core = _core(wait_for_tracks=True)
    # the estimator publishes (empty) tracks from its first period on, before any scan; the
    # vehicle, told to stay still, is at rest
    for k in range(6):
        t = 0.05 + 0.1 * k
        core.deliver(_estimate(t - 0.05, v=0.0))
        core.deliver(_tracks(t - 0.05))
        out = core.step(t)
        assert _paths(out) == []  # no plan yet: the vehicle is told to stay still
        (cmd,) = _cmds(out)
        assert (cmd.v, cmd.w) == (0.0, 0.0)
    # the first scan is fused: a moving obstacle parked on the straight way at x = 12
    parked = Track(
        id=40, x=12.0, y=20.0, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=1.5, covariance=COV6
    )
    core.deliver(_estimate(0.6, v=0.0))
    core.deliver(_tracks(0.6, parked))
    (path,) = _paths(core.step(0.65))
    assert path.status == "OK"
    assert core.last_result is not None
    # eq. (12)-(13): the plan keeps clear of the track it waited for. Heading at it from
    # 6 m, no curve within R_min leaves along the heading: the plan first turns away on an
    # arc, which may enter the safety margin (recover.py: at rest, holding first cannot
    # help, evade.py), never the hull
    res = core.last_result
    assert res.min_clearance_m >= (core.cfg.rho0_m if res.turn_rad == 0.0 else 0.0), res


def test_without_tracks_the_first_plan_comes_after_the_bounded_wait_and_says_why(
    caplog: pytest.LogCaptureFixture,
) -> None:
    core = _core(["planner.first_plan_wait_s=1.0"], wait_for_tracks=True)
    planned_at = []
    with caplog.at_level(logging.INFO, logger="tidelink.planner"):
        for k in range(20):
            t = 0.05 + 0.1 * k
            core.deliver(_estimate(t - 0.05))
            core.deliver(_tracks(t - 0.05))  # nothing in sonar range: always empty
            if _paths(core.step(t)):
                planned_at.append(t)
    # the wait is bounded by mission time first_plan_wait_s: one plan, at the first step after
    assert planned_at == [pytest.approx(1.05)]
    (why,) = [r.getMessage() for r in caplog.records if "first plan" in r.getMessage()]
    assert "first_plan_wait_s" in why and "hold none" in why


def test_a_planner_restarted_mid_mission_does_not_wait_for_tracks() -> None:
    core = _core(wait_for_tracks=True)
    core.deliver(_estimate(40.0, x=30.0, y=14.0))
    core.deliver(_tracks(40.0))  # nothing in sonar range just now
    (path,) = _paths(core.step(40.05))
    assert path.status == "OK"


def test_the_clearance_margin_widens_with_the_measured_loop_delay() -> None:
    """A plan made on estimates that arrive 1 s old aims further from the obstacles: the
    vehicle follows it on a state predicted that far ahead (planner.clearance_margin_*)."""
    near, far = _core(), _core()
    cfg = near.cfg
    near.deliver(_estimate(0.0))
    near.step(0.05)
    for k in range(10):  # estimates that arrive 1 s after their stamp
        stamp = 0.1 * k
        est = StateEstimate(stamp=stamp, x=5.0, y=20.0, theta=0.0, v=1.0, w=0.0, covariance=COV)
        far.deliver(Delivery(source="estimator", stream="state", msg=est, t=stamp + 1.0))
    assert [e for e in far.step(1.95) if e.stream == "path"]
    assert near.clearance_margin_m == pytest.approx(
        cfg.clearance_margin_m + cfg.clearance_margin_per_delay_s * 0.05, abs=0.006
    )
    assert far.clearance_margin_m == pytest.approx(
        cfg.clearance_margin_m + cfg.clearance_margin_per_delay_s * 1.0, abs=0.006
    )
    still, _ = load_scenario(DEFAULT, ["planner.clearance_margin_per_delay_s=0"])
    fixed = planner_core(still)
    for k in range(10):
        est = StateEstimate(stamp=0.1 * k, x=5.0, y=20.0, theta=0.0, v=1.0, w=0.0, covariance=COV)
        fixed.deliver(Delivery(source="estimator", stream="state", msg=est, t=0.1 * k + 1.0))
    assert fixed.clearance_margin_m == still.planner.clearance_margin_m


class _Scripted(AtOnce[PlanResult]):
    """Plans made at once, each passed through `edit` (the test's say on what they return)."""

    def __init__(self) -> None:
        super().__init__()
        self.edit: Callable[[PlanResult], PlanResult] = lambda r: r

    def start(self, work: Callable[[], PlanResult]) -> None:
        super().start(lambda: self.edit(work()))


@pytest.mark.parametrize("why", ["corridor", "cruise", "current", "infeasible"])
def test_a_precautionary_replan_keeps_the_path_in_force_over_a_recovery_or_none(
    why: ReplanReason,
) -> None:
    """A "corridor", "cruise" or "current" replan is a precaution: the path in force was still
    feasible.
    Its result replaces that path only if it is an ordinary plan; a recovery (which may turn
    about into the safety margin: fleet4 seed 8) or NO_PATH is declined and the path in force
    followed on. A replan the path in force needs ("infeasible") takes whatever it gets."""
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    plans = _Scripted()
    core = planner_core(s, plans=plans)
    core.deliver(_estimate(0.0))
    (first,) = [e.msg for e in core.step(0.05) if e.stream == "path"]
    assert isinstance(first, PathMsg) and first.status == "OK"
    in_force = core.ref
    asked = ReplanDecision(replan=True, reason=why, detail="a test's", conflict_s=math.inf)
    core.policy.check = lambda *a, **k: asked  # type: ignore[method-assign]
    recoveries = [
        lambda r: dataclasses.replace(r, escape_m=6.3, reason="no curve leaves along the heading"),
        lambda r: PlanResult(status="NO_PATH", reason="walled off", strategy="no_route"),
    ]
    for k, recovery in enumerate(recoveries):
        plans.edit = recovery
        t = 1.5 + 1.1 * k
        core.deliver(_estimate(t - 0.05, x=5.0 + t))
        out = core.step(t)
        paths = [e.msg for e in out if e.stream == "path"]
        assert [e for e in out if e.stream == "cmd"]  # commanding on, either way
        if why in PRECAUTIONS:
            assert paths == [] and core.ref is in_force and core.adoption.declined == k + 1
            assert core.stats_counters[PLANS_DECLINED] == k + 1  # the metric's source
            # the interval before the next replan runs from this one (no re-asking each step)
            assert core.policy.last_replan_t is not None and core.policy.last_replan_t >= t
        else:
            (made,) = paths
            assert isinstance(made, PathMsg) and made.reason.startswith("infeasible")
            assert core.adoption.declined == 0


def test_a_plan_made_for_a_lower_speed_is_followed_and_broadcast_at_it() -> None:
    """rollout.py makes a plan again slower when no faster one flies clear of rho0: the core
    then follows it at that speed (the controller's cruise cap), tells it in the path message
    (another vehicle predicts its intent with it) and judges the path's passing times at it
    (eq. (13)); the next plan made for cruise speed restores it."""
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    plans = _Scripted()
    slow = 0.5 * s.vehicle.cruise_speed_mps
    plans.edit = lambda r: dataclasses.replace(r, v_ref_mps=slow)
    core = planner_core(s, plans=plans)
    core.deliver(_estimate(0.0))
    (made,) = _paths(core.step(0.05))
    assert made.status == "OK" and made.v_ref == slow
    assert core.ref is not None and core.ref.v_ref == slow and core.policy.v_ref == slow
    top = 0.0
    for k in range(1, 40):  # 4 s along it, the vehicle at the speed commanded
        t = 0.05 + 0.1 * k
        core.deliver(_estimate(t - 0.05, x=5.0 + slow * t))
        (cmd,) = _cmds(core.step(t))
        top = max(top, cmd.v, *cmd.v_next)
    assert slow - 0.01 < top <= slow + 1e-9
    plans.edit = lambda r: r
    core.policy.check = lambda *a, **k: ReplanDecision(  # type: ignore[method-assign]
        replan=True, reason="infeasible", detail="a test's"
    )
    t = 4.15
    core.deliver(_estimate(t - 0.05, x=5.0 + slow * t))
    (again,) = _paths(core.step(t))
    assert again.v_ref == s.vehicle.cruise_speed_mps == core.policy.v_ref


def test_a_way_aside_is_kept_until_a_plan_reaches_the_goal() -> None:
    """evade.py: a way aside (short of the goal) stays in force when a replan finds no path
    (its NO_PATH judged going on along it as good as any way aside); a plan to the goal, or a
    new way aside that clears more, replaces it."""
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    plans = _Scripted()
    plans.edit = lambda r: dataclasses.replace(r, short_of_goal=True)
    core = planner_core(s, plans=plans)
    core.deliver(_estimate(0.0))
    (aside,) = _paths(core.step(0.05))
    assert aside.status == "OK" and core.last_result is not None
    in_force = core.ref
    plans.edit = lambda r: PlanResult(status="NO_PATH", reason="walled off", strategy="no_route")
    t = 1.15
    core.deliver(_estimate(t - 0.05, x=5.0 + t))
    out = core.step(t)
    assert _paths(out) == [] and core.ref is in_force and _cmds(out)  # kept, commanding on
    # run to its end, the vehicle stops either way, and the NO_PATH is told (and alarmed on)
    ended = copy.deepcopy(core)
    ended.policy.s_now = float(ended.policy.s[-1])
    ended.deliver(_estimate(2.2, x=7.2))
    (told,) = _paths(ended.step(2.25))
    assert told.status == "NO_PATH" and ended.ref is None
    plans.edit = lambda r: r
    t = 2.25
    core.deliver(_estimate(t - 0.05, x=5.0 + t))
    (made,) = _paths(core.step(t))
    assert made.status == "OK" and made.reason.startswith("aside") and core.ref is not in_force
    assert core.last_result is not None and not core.last_result.short_of_goal
