"""Vehicle core: ServiceCore contract, bit-identical determinism, collisions against truth."""

from __future__ import annotations

import math

import numpy as np

from common.config.current import CurrentConfig
from common.config.vehicle import VehicleConfig, WatchdogConfig
from common.config.world import AreaConfig
from common.messages import TruthState, VehicleStatus, VelocityCommand
from common.runtime.model.core import Delivery, ServiceCore
from common.world.current import CurrentField
from services.vehicle.core import VehicleCore


def _send(core: VehicleCore, t: float, v: float, w: float) -> None:
    msg = VelocityCommand(stamp=t - 0.02, v=v, w=w, path_id=1)
    core.deliver(Delivery(source="planner", stream="cmd", msg=msg, t=t))


def _run(seed: int) -> list[tuple[float, ...]]:
    """60 s with a Gauss-Markov current, commands at irregular off-grid times, all floats."""
    cfg = VehicleConfig()
    water = CurrentConfig(speed_mps=0.05, sigma_mps=0.1, tau_s=20.0)
    core = VehicleCore(cfg, (2.0, 3.0, 0.5), current=CurrentField(water, AreaConfig(), seed))
    rng = np.random.default_rng(99)  # the command timetable, same for every run
    t_cmd = 0.013
    rows: list[tuple[float, ...]] = []
    for k in range(1201):
        t = k * cfg.period_s
        while t_cmd <= t:
            _send(core, t_cmd, float(rng.uniform(-0.5, 2.5)), float(rng.uniform(-0.8, 0.8)))
            t_cmd += float(rng.uniform(0.02, 0.4))
        truth, status = (e.msg for e in core.step(t))
        assert isinstance(truth, TruthState) and isinstance(status, VehicleStatus)
        rows.append((truth.x, truth.y, truth.theta, truth.v, truth.w, status.v_applied))
    return rows


def test_core_keeps_the_contract() -> None:
    core = VehicleCore(VehicleConfig(period_s=0.1), (0.0, 0.0, 0.0))
    assert isinstance(core, ServiceCore)
    # deliver never publishes; step publishes truth and status stamped at t
    assert (
        core.deliver(
            Delivery(
                source="planner",
                stream="cmd",
                msg=VelocityCommand(stamp=0.0, v=1.0, w=0.0, path_id=0),
                t=0.0,
            )
        )
        == []
    )
    out = core.step(0.1)
    assert [e.stream for e in out] == ["truth", "status"]
    assert all(e.msg.stamp == 0.1 for e in out)


def test_two_identical_runs_are_bit_identical() -> None:
    a, b = _run(5), _run(5)
    assert a == b  # exact float equality, every field, every step
    c = _run(6)
    assert a != c  # the seed drives the current: another seed, another trajectory


def test_off_grid_output_times_do_not_disturb_the_trajectory() -> None:
    # extra step() calls at off-grid times (a wake-up runtime) only read the state: the
    # on-grid samples stay bit-identical to a run without them
    cfg = VehicleConfig()
    cores = [VehicleCore(cfg, (0.0, 0.0, 0.0)) for _ in range(2)]
    grid: list[list[tuple[float, float]]] = [[], []]
    for k in range(401):
        t = k * 0.05
        for i, core in enumerate(cores):
            if k % 4 == 0:
                _send(core, t, 1.3, 0.2 * math.sin(t))
            if i == 1 and k > 0:
                core.step(t - 0.0137)  # off-grid read
            msg = core.step(t)[0].msg
            assert isinstance(msg, TruthState)
            grid[i].append((msg.x, msg.y))
    assert grid[0] == grid[1]


def test_collision_flag_from_the_clearance_function() -> None:
    # eq. (12): an obstacle of radius 1 m at (10, 0) and a vehicle radius of 0.8 m; driving
    # along y = 0 the clearance is negative for 8.2 < x < 11.8 and the truth says collided
    # exactly there
    cfg = VehicleConfig()

    def clearance(x: float, y: float, t: float) -> float:
        return math.hypot(x - 10.0, y) - (cfg.radius_m + 1.0)

    core = VehicleCore(cfg, (0.0, 0.0, 0.0), clearance)
    flags = []
    for k in range(301):
        t = k * 0.05
        if k % 2 == 0:
            _send(core, t, 1.0, 0.0)
        truth = core.step(t)[0].msg
        assert isinstance(truth, TruthState)
        flags.append((truth.x, truth.collided))
    assert any(c for _, c in flags)
    assert all(c == (8.2 < x < 11.8) for x, c in flags)  # inside the inflated disc
    assert core.min_clearance_m < 0.0 and core.collisions == sum(c for _, c in flags)


def test_other_messages_are_ignored() -> None:
    core = VehicleCore(VehicleConfig(), (0.0, 0.0, 0.0))
    other = TruthState(stamp=0.0, x=0.0, y=0.0, theta=0.0, v=0.0, w=0.0)
    assert core.deliver(Delivery(source="x", stream="y", msg=other, t=0.0)) == []
    assert core.watchdog.applied == 0 and core.watchdog.rejected == 0


def test_a_restarted_core_resumes_the_hull_where_its_last_truth_was() -> None:
    cfg = VehicleConfig()
    before = VehicleCore(cfg, (0.0, 0.0, 0.0))
    for k in range(1, 201):  # 10 s at 1.5 m/s, turning gently
        t = k * cfg.period_s
        _send(before, t, 1.5, 0.05)
        last = before.step(t)[0].msg
    assert isinstance(last, TruthState) and math.hypot(last.x, last.y) > 8.0
    after = VehicleCore(cfg, (0.0, 0.0, 0.0))  # the new process
    gap = 2.3  # the restart took this long; no command was in force meanwhile
    what = after.resume({"truth": last}, last.stamp + gap)
    assert what is not None and f"t={last.stamp:.2f} s" in what
    first = after.step(last.stamp + gap)[0].msg
    assert isinstance(first, TruthState)
    moved = math.hypot(first.x - last.x, first.y - last.y)
    # it coasted on along its heading while braking (IDLE): less than at full speed, not back
    # at the start pose
    assert 0.5 < moved < last.v * gap
    along = (first.x - last.x) * math.cos(last.theta) + (first.y - last.y) * math.sin(last.theta)
    assert along > 0.9 * moved
    assert first.v < last.v and after.applied(first.stamp).mode == "IDLE"


def test_a_core_without_a_usable_truth_starts_over() -> None:
    cfg = VehicleConfig()
    core = VehicleCore(cfg, (5.0, 6.0, 0.0))
    future = TruthState(stamp=20.0, x=50.0, y=50.0, theta=0.0, v=1.0, w=0.0)
    assert core.resume({}, 10.0) is None
    assert core.resume({"truth": future}, 10.0) is None  # from after the restart: not its own
    truth = core.step(10.0)[0].msg
    assert isinstance(truth, TruthState) and (truth.x, truth.y) == (5.0, 6.0)


def _integrate_by_candidates(
    core: VehicleCore, state: tuple[float, ...], t_a: float, t_b: float
) -> tuple[float, ...]:
    """The integrator as it was: every piece start and schedule transition in (t_a, t_b - tol)
    sorted, the applied (v, w) looked up at each, a cut where it changes (the oracle)."""
    hi = t_b - 1e-9
    pieces = core._pieces
    cands = [start for start, _ in pieces if t_a < start < hi]
    for _, sc in pieces:
        cands += [x for x in sc.transitions_between(t_a, t_b) if x < hi]
    seg_a, cur = t_a, core._applied_vw(t_a)
    for c in sorted(cands):
        val = core._applied_vw(c)
        if val != cur:
            state = core._rk4(state, seg_a, c, cur)
            seg_a, cur = c, val
    return core._rk4(state, seg_a, t_b, cur)


def test_the_integrator_cuts_where_the_oracle_does_bit_for_bit() -> None:
    """Sequences (entries every 0.03-0.2 s, on and off the grid), up to four deliveries inside
    a cell, HOLD ramps and FAILSAFE: every off-grid state the integrator makes from the
    committed one equals the candidate-by-candidate oracle's, float for float."""
    cfg = VehicleConfig(
        watchdog=WatchdogConfig(
            max_command_age_s=0.3, hold_after_s=0.3, failsafe_after_s=0.7, hold_decel_mps2=0.5
        )
    )
    core = VehicleCore(cfg, (0.0, 0.0, 0.0), start_speed_mps=0.5)
    rng = np.random.default_rng(7)
    t, checked, pieces = 0.0, 0, 0
    for _ in range(600):
        t += float(rng.choice([0.002, 0.003, 0.013, 0.05, 0.4, 1.0]))
        n = int(rng.integers(0, 6))
        msg = VelocityCommand.predictive(
            stamp=t - 0.05,
            v=float(rng.uniform(0.0, 2.0)),
            w=float(rng.uniform(-0.3, 0.3)),
            path_id=1,
            step_s=float(rng.choice([0.003, 0.03, 0.2])) if n else 0.0,
            v_next=[float(x) for x in rng.uniform(0.0, 2.0, n)],
            w_next=[float(x) for x in rng.uniform(-0.3, 0.3, n)],
        )
        core.deliver(Delivery(source="planner", stream="cmd", msg=msg, t=t))
        # a scratch state ahead of the committed one, within its cell or past the delivery
        t_b = core.time + float(rng.uniform(1e-10, cfg.dt_internal_s))
        want = _integrate_by_candidates(core, core._state, core.time, t_b)
        assert core._integrate(core._state, core.time, t_b) == want
        checked += 1
        pieces += len(core._pieces) > 2
    assert checked == 600 and pieces > 50
