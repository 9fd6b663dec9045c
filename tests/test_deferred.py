"""Work a core hands off: at once in virtual time, in a thread on the wall clock; and the
planner core going on commanding on its path while a replan is being made."""

from __future__ import annotations

import threading
from collections.abc import Callable
from pathlib import Path

import pytest
from helpers.planner_world import planner_core

from common.config.scenario import load_scenario
from common.messages import ObstacleTracks, PathMsg, StateEstimate, Track, VelocityCommand
from common.runtime.deferred import AtOnce, InThread
from common.runtime.model.core import Delivery
from services.planner.core import PlannerCore
from services.planner.plan import PlanResult

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))
COV6 = tuple(0.01 if i % 7 == 0 else 0.0 for i in range(36))
WAIT_S = 10.0


def test_at_once_has_the_result_in_the_step_that_started_it() -> None:
    d: AtOnce[int] = AtOnce()
    assert not d.running and d.result() is None
    d.start(lambda: 42)
    assert d.running
    with pytest.raises(RuntimeError, match="already running"):
        d.start(lambda: 0)
    assert d.result() == 42
    assert not d.running and d.result() is None  # taken once


def test_an_exception_of_the_work_is_raised_where_its_result_is_taken() -> None:
    def fails() -> int:
        raise ValueError("no plan")

    for d in (AtOnce[int](), InThread[int]()):
        d.start(fails)
        if isinstance(d, InThread):
            assert d._thread is not None
            d._thread.join(WAIT_S)
        with pytest.raises(ValueError, match="no plan"):
            d.result()
        assert not d.running


def test_in_thread_runs_beside_the_caller_until_the_work_is_done() -> None:
    go, started = threading.Event(), threading.Event()
    caller = threading.get_ident()
    ran_in: list[int] = []

    def work() -> str:
        ran_in.append(threading.get_ident())
        started.set()
        assert go.wait(WAIT_S)
        return "path"

    d: InThread[str] = InThread()
    d.start(work)
    assert started.wait(WAIT_S)
    assert d.running and d.result() is None  # still working: the caller goes on
    go.set()
    assert d._thread is not None
    d._thread.join(WAIT_S)
    assert d.result() == "path" and not d.running
    assert ran_in and ran_in[0] != caller


class HeldPlans:
    """A Deferred whose work waits until the test lets it go (a replan taking long)."""

    def __init__(self) -> None:
        self.work: Callable[[], PlanResult] | None = None
        self.done: PlanResult | None = None
        self.started = 0

    @property
    def running(self) -> bool:
        return self.work is not None or self.done is not None

    def start(self, work: Callable[[], PlanResult]) -> None:
        assert not self.running
        self.work, self.started = work, self.started + 1

    def finish(self) -> None:
        assert self.work is not None
        self.done, self.work = self.work(), None

    def result(self) -> PlanResult | None:
        done, self.done = self.done, None
        return done


def _estimate(t: float, x: float, y: float = 20.0) -> Delivery:
    est = StateEstimate(stamp=t, x=x, y=y, theta=0.0, v=1.0, w=0.0, covariance=COV)
    return Delivery(source="estimator", stream="state", msg=est, t=t + 0.05)


def test_the_planner_commands_on_its_path_while_a_replan_is_made() -> None:
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    held = HeldPlans()
    core = planner_core(s, plans=held)
    core.deliver(_estimate(0.0, 5.0))
    out = core.step(0.05)  # the first plan is asked for: until it is there, a stop
    assert held.started == 1 and not [e for e in out if e.stream == "path"]
    (stop,) = [e.msg for e in out if e.stream == "cmd"]
    assert isinstance(stop, VelocityCommand) and (stop.v, stop.w) == (0.0, 0.0)
    held.finish()
    out = core.step(0.15)  # adopted in the next step, stamped when sent
    (path,) = [e.msg for e in out if e.stream == "path"]
    assert isinstance(path, PathMsg) and path.status == "OK" and path.stamp == 0.15
    (cmd,) = [e.msg for e in out if e.stream == "cmd"]
    assert isinstance(cmd, VelocityCommand) and cmd.v > 0.0 and cmd.path_id == path.path_id
    # past the minimum replan interval the vehicle is 6 m off its path (a replan is due): it
    # is asked for once, and the steps go on commanding on the path in force, none asking
    # again, until it is there
    t0 = 0.15 + s.planner.min_replan_interval_s
    core.deliver(_estimate(t0, 5.0, y=26.0))
    asked_before = held.started
    for k in range(5):
        t = t0 + 0.05 + 0.1 * k
        core.deliver(_estimate(t - 0.05, 5.0, y=26.0))
        out = core.step(t)
        cmds = [e.msg for e in out if e.stream == "cmd"]
        assert len(cmds) == 1 and isinstance(cmds[0], VelocityCommand)
        assert cmds[0].path_id == path.path_id and cmds[0].v > 0.0
        assert not [e for e in out if e.stream == "path"]
    assert held.started == asked_before + 1, "a replan is asked for once while one is made"
    held.finish()
    core.deliver(_estimate(t + 0.05, 5.0, y=26.0))
    (new,) = [e.msg for e in core.step(t + 0.1) if e.stream == "path"]
    assert isinstance(new, PathMsg) and new.path_id == path.path_id + 1


def test_a_plan_the_vehicle_has_left_behind_while_it_was_made_is_declined_and_asked_again() -> None:
    # a loaded machine: the plan for where the vehicle was is done when it is 6 m on
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    held = HeldPlans()
    core = planner_core(s, plans=held)
    core.deliver(_estimate(0.0, 5.0))
    core.step(0.05)
    held.finish()
    (path,) = [e.msg for e in core.step(0.15) if e.stream == "path"]
    t = 0.15 + s.planner.min_replan_interval_s
    core.deliver(_estimate(t - 0.05, 5.0, y=26.0))  # 6 m off its path: a replan is asked
    asked = held.started
    core.step(t)
    assert held.started == asked + 1
    held.finish()
    core.deliver(_estimate(t + 0.95, 5.0, y=32.0))  # a second later, 6 m on, off the plan
    out = core.step(t + 1.0)
    assert not [e for e in out if e.stream == "path"], "a plan from where it was is adopted"
    assert core.path_id == path.path_id and core.adoption.declined == 1
    cmds = [e.msg for e in out if e.stream == "cmd"]
    assert len(cmds) == 1 and isinstance(cmds[0], VelocityCommand)
    assert cmds[0].path_id == path.path_id  # still commanding on the path in force
    core.deliver(_estimate(t + 1.05, 5.0, y=32.0))
    core.step(t + 1.1)
    assert held.started == asked + 2  # and the next step asks afresh, from where it is now
    held.finish()
    core.deliver(_estimate(t + 1.15, 5.0, y=32.0))
    (new,) = [e.msg for e in core.step(t + 1.2) if e.stream == "path"]
    assert isinstance(new, PathMsg) and new.path_id == path.path_id + 1


def _on(core: PlannerCore, t: float, s: float, v: float = 1.0) -> Delivery:
    """An estimate stamped t of a vehicle at arc length s on the path in force, moving at v."""
    assert core.ref is not None
    x, y = core.ref.point_at_s(s)
    est = StateEstimate(
        stamp=t, x=x, y=y, theta=core.ref.heading_at_s(s), v=v, w=0.0, covariance=COV
    )
    return Delivery(source="estimator", stream="state", msg=est, t=t + 0.05)


def test_a_slow_replan_starts_where_the_vehicle_will_be_and_it_stops_short_of_the_conflict() -> (
    None
):
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0"])
    held = HeldPlans()
    core = planner_core(s, plans=held)
    core.deliver(_estimate(0.0, 5.0))
    core.step(0.05)
    for k in range(1, 20):  # the first plan takes 2 s
        core.deliver(_estimate(0.05 * k, 5.0))
        core.step(0.05 + 0.1 * k)
    held.finish()
    core.deliver(_estimate(2.0, 5.0))
    (first,) = [e.msg for e in core.step(2.05) if e.stream == "path"]
    assert isinstance(first, PathMsg) and first.status == "OK" and core.ref is not None
    ref = core.ref
    # under way on it; then a track parked on the path 12 m ahead: infeasible
    t = 2.05
    for k in range(1, 15):
        t = 2.05 + 0.1 * k
        core.deliver(_on(core, t - 0.05, 0.1 * k))
        core.step(t)
    s_here = ref.closest_s(*ref.point_at_s(1.4), None)
    px, py = ref.point_at_s(s_here + 12.0)
    parked = Track(id=40, x=px, y=py, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=1.0, covariance=COV6)
    core.deliver(Delivery("estimator", "tracks", ObstacleTracks(stamp=t, tracks=(parked,)), t))
    t += 0.1
    core.deliver(_on(core, t - 0.05, 1.5))
    asked = held.started
    core.step(t)
    assert held.started == asked + 1  # the replan is asked for
    # the vehicle must stop short of where the path comes within r + rho0 of the track's edge
    reach = 1.0 + s.vehicle.radius_m + s.planner.rho0_m
    assert s_here + 12.0 - reach - 0.6 < ref.stop_s < s_here + 12.0 - reach
    # the plan is made for 2 s on (as long as the last took), from the path 2 s ahead
    held.finish()
    new = core.last_result
    core.deliver(_on(core, t + 0.05, 1.6))
    out = core.step(t + 0.1)
    (path,) = [e.msg for e in out if e.stream == "path"]
    assert path.status == "OK" and core.last_result is not new and core.last_result is not None
    x0, y0 = core.last_result.control_points[0]
    ahead = ref.closest_s(x0, y0, None) - 1.5
    assert 1.0 < ahead < 4.0, ahead  # v 1-1.5 m/s over the 2 s the last plan took
