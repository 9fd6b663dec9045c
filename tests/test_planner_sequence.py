"""The planner's end of issue 16: the vehicle response model, the command timeline, command
sequences, measured delays and staleness beyond them."""

from __future__ import annotations

import copy
import itertools
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers.planner_world import planner_core

from common.config.controller import ControllerConfig
from common.config.scenario import load_scenario
from common.messages import StateEstimate, VehicleStatus, VelocityCommand, encode
from common.runtime.model.core import Delivery
from services.control.command.response import Pose, ResponseModel
from services.control.command.sequence import command_sequence
from services.control.command.timeline import CommandTimeline
from services.control.controllers import Circle, Controller, Limits, make_controller
from services.planner.core import PlannerCore
from services.vehicle.dynamics import PlantParams, rk4_step

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))
SCENARIO = load_scenario(DEFAULT)[0]
MODEL = ResponseModel.from_vehicle(SCENARIO.vehicle)


def _core(overrides: list[str] | None = None, *, downlink_s: float = 0.0) -> PlannerCore:
    s, _ = load_scenario(DEFAULT, ["planner.first_plan_wait_s=0", *(overrides or [])])
    return planner_core(s, expected_downlink_s=downlink_s)


def _estimate(
    stamp: float, t: float, *, x: float = 5.0, v: float = 0.0, y: float = 20.0
) -> Delivery:
    est = StateEstimate(stamp=stamp, x=x, y=y, theta=0.0, v=v, w=0.0, covariance=COV)
    return Delivery(source="estimator", stream="state", msg=est, t=t)


def _status(stamp: float, delay_s: float, jitter_s: float = 0.0, n: int = 10) -> Delivery:
    st = VehicleStatus(
        stamp=stamp,
        mode="RUN",
        v_applied=0.0,
        w_applied=0.0,
        command_age=0.0,
        commands_applied=n,
        commands_rejected=0,
        commands_clamped=0,
        delay_s=delay_s,
        delay_jitter_s=jitter_s,
        delay_samples=n,
    )
    return Delivery(source="vehicle", stream="status", msg=st, t=stamp + 0.05)


def _cmd(core: PlannerCore, t: float) -> VelocityCommand:
    (cmd,) = [e.msg for e in core.step(t) if isinstance(e.msg, VelocityCommand)]
    return cmd


# --- the vehicle response model (response.py) -----------------------------------------------


def _plant(pose: tuple[float, ...], cmds: list[tuple[float, float]], step_s: float) -> tuple:
    """The vehicle's own plant (an independent oracle) under a command every step_s."""
    p = PlantParams.from_config(SCENARIO.vehicle)
    s = (*pose, 0.0)
    for v, w in cmds:
        for _ in range(round(step_s / 0.01)):
            s = rk4_step(s, 0.01, v, w, p)
    return s[:5]


def test_the_model_follows_the_plant_within_centimetres_over_two_seconds() -> None:
    # commands as the controllers give them: the speed ramped (0.2 m/s^2, the shared
    # profile), the yaw rate anywhere within R_min, changing every 0.1 s
    rng = np.random.default_rng(7)
    for _ in range(20):
        v0 = float(rng.uniform(0.3, 1.8))
        pose = (0.0, 0.0, float(rng.uniform(-3, 3)), v0, float(rng.uniform(-0.8, 0.8)) * v0 / 5)
        speeds = np.clip(v0 + np.cumsum(rng.uniform(-0.02, 0.02, 20)), 0.0, 1.8)
        cmds = [(float(v), float(rng.uniform(-0.3, 0.3))) for v in speeds]
        got = pose
        for v, w in cmds:
            got = MODEL.advance(got, v, w, 0.1)
        want = _plant(pose, cmds, 0.1)
        assert math.hypot(got[0] - want[0], got[1] - want[1]) < 0.02
        assert abs(got[3] - want[3]) < 0.01 and abs(got[4] - want[4]) < 0.01


def test_the_model_never_turns_tighter_than_r_min() -> None:
    pose = (0.0, 0.0, 0.0, 0.2, 0.0)
    for _ in range(100):  # accelerating from 0.2 m/s while asked for the tightest turn
        pose = MODEL.advance(pose, 1.5, 0.5, 0.05)
        assert abs(pose[4]) <= pose[3] / SCENARIO.vehicle.turn_radius_min_m + 1e-12


# --- what the vehicle applies, as the planner expects it (timeline.py) ----------------------


def _timeline() -> CommandTimeline:
    return CommandTimeline(SCENARIO.vehicle.watchdog, SCENARIO.vehicle.v_min_mps)


def test_the_newest_command_arrived_is_in_force_and_its_buffer_ends_in_hold() -> None:
    tl = _timeline()
    assert tl.schedule_at(1.0).at(1.0).mode == "IDLE"
    tl.add(1.0, 2.0, 0.1, [1.0, 1.1, 1.2], [0.0, 0.1, 0.2])
    tl.add(1.1, 1.9, 0.1, [0.5], [0.0])  # newer, expected earlier (the delay fell)
    assert tl.schedule_at(1.85).stamp is None  # nothing has arrived yet
    assert tl.schedule_at(1.95).stamp == 1.1
    assert tl.schedule_at(2.05).stamp == 1.1  # the older one arrives later: overtaken
    hold = SCENARIO.vehicle.watchdog.hold_after_s
    assert tl.schedule_at(1.1 + hold + 0.01).at(1.1 + hold + 0.01).mode == "HOLD"


def test_forgetting_what_is_superseded_changes_no_prediction() -> None:
    tl = _timeline()
    for k in range(40):  # a sequence every 0.1 s, 0.5 s in flight
        t = 0.1 * k
        tl.add(t, t + 0.5, 0.1, [1.0 + 0.01 * k] * 20, [0.1 * math.sin(k / 3)] * 20)
    start = (0.0, 0.0, 0.0, 1.0, 0.0)
    full = tl.predict(start, 3.0, 4.5, MODEL)
    tl.forget_before(3.0)
    assert len(tl.sent) == 15  # the one in force at 3.0 (stamp 2.5) and every later one
    assert tl.predict(start, 3.0, 4.5, MODEL) == full


def _predicted_command_by_command(
    tl: CommandTimeline, pose: tuple[float, ...], t_a: float, t_b: float
) -> tuple[float, ...]:
    """CommandTimeline.predict as first written (the oracle of its sweep): the command in
    force looked up afresh, and every command sent scanned, for each command in force."""
    t = t_a
    while t < t_b:
        sched = tl.schedule_at(t)
        newer = -math.inf if sched.stamp is None else sched.stamp
        end = min([t_b] + [s.arrival for s in tl.sent if t < s.arrival < t_b and s.stamp > newer])
        for c in sorted({end, *sched.transitions_between(t, end)}):
            pose = MODEL.advance(pose, *sched.vw_at(t), c - t)  # type: ignore[arg-type]
            t = c
    return pose


def test_a_prediction_applies_the_commands_in_force_one_after_another() -> None:
    rng = np.random.default_rng(7)
    for _ in range(30):
        tl = _timeline()
        stamps = np.round(np.cumsum(rng.choice([0.0, 0.05, 0.1], size=25)), 2)
        for k, t in enumerate(stamps):  # repeated stamps; arrivals out of order, some tied
            arrival = float(t + rng.choice([0.1, 0.15, 0.3, 0.6]))
            n = int(rng.integers(1, 8))
            tl.add(float(t), arrival, 0.05, [0.5 + 0.01 * k] * n, [0.02 * (k % 5 - 2)] * n)
        start = (0.0, 0.0, 0.0, 1.0, 0.0)
        t_a = float(rng.uniform(0.0, stamps[-1]))
        t_b = t_a + float(rng.uniform(0.0, 3.0))
        expected = _predicted_command_by_command(tl, start, t_a, t_b)
        assert tl.predict(start, t_a, t_b, MODEL) == expected


def test_the_twist_alone_is_the_same_floats_as_the_whole_state() -> None:
    pose = (3.0, -2.0, 0.7, 0.4, -0.05)
    for v_c, w_c, dt in [(1.5, 0.3, 0.05), (0.2, -0.4, 0.73), (0.0, 0.0, 0.02)]:
        whole = MODEL.advance(pose, v_c, w_c, dt)
        alone = MODEL.advance(pose, v_c, w_c, dt, True)
        assert alone[:3] == pose[:3] and alone[3:] == whole[3:]


# --- command sequences (sequence.py) ----------------------------------------------------------


CIRCLE = Circle(cx=0.0, cy=10.0, radius=10.0, phase0=-0.5 * math.pi, turns=1.0)
LIMITS = Limits.from_vehicle(SCENARIO.vehicle)


@pytest.mark.parametrize("kind", ["nurbs", "backstepping", "fuzzy_pid"])
def test_a_controllers_copy_has_a_state_of_its_own(kind: str) -> None:
    ctrl, witness = (make_controller(ControllerConfig(kind=kind), LIMITS) for _ in range(2))
    pose = (0.5, -0.3, 0.1, 1.2, 0.05)
    for k in range(5):  # the same history: integrals, a virtual reference, a ramp
        assert ctrl.command(0.1 * k, pose, CIRCLE) == witness.command(0.1 * k, pose, CIRCLE)
    twin = copy.deepcopy(ctrl)
    assert _state(twin) == _state(ctrl)
    for k in range(5, 9):  # the copy driven on alone, elsewhere
        twin.command(0.1 * k, (0.7, -0.2, 0.2, 1.0, -0.1), CIRCLE)
    assert _state(ctrl) == _state(witness)  # ... the controller has not seen it
    for k in range(5, 9):
        assert ctrl.command(0.1 * k, pose, CIRCLE) == witness.command(0.1 * k, pose, CIRCLE)


@pytest.mark.parametrize("kind", ["nurbs", "backstepping", "fuzzy_pid"])
def test_a_sequence_is_the_controller_rolled_on_a_copy(kind: str) -> None:
    ctrl = make_controller(ControllerConfig(kind=kind), LIMITS)
    pose = (0.5, -0.3, 0.1, 1.2, 0.05)
    for k in range(5):  # some history: integrals, a virtual reference, a ramp
        ctrl.command(0.1 * k, pose, CIRCLE)
    alone = copy.deepcopy(ctrl)
    tl = _timeline()
    tl.add(0.2, 0.45, 0.1, [1.0] * 10, [0.08] * 10)  # in force at the vehicle until 0.75 s
    t, arrival = 0.5, 0.75
    vs, ws = command_sequence(
        ctrl, CIRCLE, t, pose, n=30, step_s=0.1, arrival=arrival, timeline=tl, model=MODEL
    )
    assert len(vs) == len(ws) == 31  # now, and every step of the 3 s horizon
    # entry 0 is the command for now: what the controller alone answers for that pose,
    # and the controller's own state moved exactly as by that one call
    assert (vs[0], ws[0]) == alone.command(t, pose, CIRCLE)
    assert _state(ctrl) == _state(alone)
    # entry k: the controller (a copy) on the state predicted for t + 0.1 k: the vehicle
    # applies the command sent before until this one arrives, then this one's entries
    p = tl.predict(pose, t, t + 0.1, MODEL)
    assert (vs[1], ws[1]) == alone.command(t + 0.1, p, CIRCLE)
    p = tl.predict(p, t + 0.1, t + 2 * 0.1, MODEL)
    assert (vs[2], ws[2]) == alone.command(t + 2 * 0.1, p, CIRCLE)
    p = tl.predict(p, t + 2 * 0.1, arrival, MODEL)  # then entry 2 from its arrival on
    p = MODEL.advance(p, vs[2], ws[2], t + 3 * 0.1 - arrival)
    assert (vs[3], ws[3]) == alone.command(t + 3 * 0.1, p, CIRCLE)
    p = MODEL.advance(p, vs[3], ws[3], 0.1)
    assert (vs[4], ws[4]) == alone.command(t + 4 * 0.1, p, CIRCLE)


def _braking_sequence(kind: str) -> tuple[Controller, Pose, dict[str, Any]]:
    """A controller of `kind`, a pose, and command_sequence's other arguments for a 3 s
    horizon at 0.1 s with the stop tail, a command from before in flight until 0.75 s."""
    tl = _timeline()
    tl.add(0.2, 0.45, 0.1, [1.0] * 10, [0.08] * 10)
    ctrl = make_controller(ControllerConfig(kind=kind), LIMITS)
    args = dict(n=30, step_s=0.1, arrival=0.75, timeline=tl, model=MODEL, stop_mps2=0.5)
    return ctrl, (0.5, -0.3, 0.1, 1.6, 0.05), args


@pytest.mark.parametrize("kind", ["nurbs", "backstepping", "fuzzy_pid"])
def test_the_first_entries_are_the_same_floats_whatever_is_computed_after_them(kind: str) -> None:
    # a step computes entries 0..last only (prepared tails): they must be the entries of
    # the whole sequence, bit for bit, the stop tail's cap (set by the horizon) included
    ctrl, pose, args = _braking_sequence(kind)
    whole = command_sequence(copy.deepcopy(ctrl), CIRCLE, 2.5, pose, **args)
    for last in (0, 1, 6, 30, 40):
        part = command_sequence(copy.deepcopy(ctrl), CIRCLE, 2.5, pose, last=last, **args)
        k = min(last, 30) + 1
        assert part == (whole[0][:k], whole[1][:k])
    assert whole[0][-1] == 0.0  # the stop tail brakes to rest by the horizon's end


@pytest.mark.parametrize("kind", ["nurbs", "backstepping", "fuzzy_pid"])
def test_past_fine_the_controller_is_asked_every_mth_entry_and_its_answer_held(kind: str) -> None:
    # coarse far entries: up to `fine` the entries of a sequence asked at every entry, bit for
    # bit; past it the controller's answer for the state carried entry by entry under what
    # is held, asked at fine + m, fine + 2m, ... and held (the stop tail still capping v)
    ctrl, pose, args = _braking_sequence(kind)
    every = command_sequence(copy.deepcopy(ctrl), CIRCLE, 2.5, pose, **args)
    poses: list[Pose] = []
    vs, ws = command_sequence(
        copy.deepcopy(ctrl), CIRCLE, 2.5, pose, fine=10, coarse_every=3, poses=poses, **args
    )
    assert len(vs) == len(poses) == 31
    assert (vs[:11], ws[:11]) == (every[0][:11], every[1][:11])
    witness = copy.deepcopy(ctrl)
    for k in range(11):  # the witness controller through the fine entries, as asked
        v, w = witness.command(2.5 + 0.1 * k, poses[k], CIRCLE)
    for k in range(11, 31):
        asked = (k - 10) % 3 == 0
        if asked:
            v, w = witness.command(2.5 + 0.1 * k, poses[k], CIRCLE)
        # the state carried one entry under entry k - 1 as sent
        dt = (2.5 + k * 0.1) - (2.5 + (k - 1) * 0.1)
        assert poses[k] == MODEL.advance(poses[k - 1], vs[k - 1], ws[k - 1], dt)
        assert ws[k] == w
        assert vs[k] == min(v, 0.5 * max(0.0, 2.5 + 3.0 - (2.5 + 0.1 * k)))
        if not asked:
            assert ws[k] == ws[k - 1]
    assert vs[-1] == 0.0  # the stop tail brakes to rest by the horizon's end all the same


def test_a_config_past_fine_asks_every_coarse_step() -> None:
    seq = SCENARIO.controller.sequence
    assert (seq.fine_s, seq.coarse_step_s) == (3.0, 0.3)
    assert seq.coarse(0.1) == (30, 3)
    assert seq.coarse(0.5) == (6, 1)  # a coarse step under the period: every entry asked
    with pytest.raises(ValueError, match="fine_s"):
        load_scenario(DEFAULT, ["controller.sequence.fine_s=-1"])


def _twins(reuse: bool = False) -> tuple[PlannerCore, PlannerCore]:
    """A planner with prepared tails (the default fresh_s; `reuse`: and reused tails, else
    one rolled out after every step) and one computing every entry in the step, both at a
    0.2 s downlink delay."""
    every = _core(["controller.sequence.fresh_s=10"], downlink_s=0.2)
    return _core([] if reuse else ["controller.sequence.reuse_s=0"], downlink_s=0.2), every


def _feed(core: PlannerCore, k: int) -> VelocityCommand:
    """Step k (t = 0.05 + 0.1 k) on an estimate along y = 20 at 1.2 m/s, then prepare the next
    (times as a runtime gives them: whole microseconds)."""
    t = round(0.05 + 0.1 * k, 6)
    core.deliver(_estimate(t - 0.05, t - 0.02, x=5.0 + 1.2 * (t - 0.05), v=1.2))
    cmd = _cmd(core, t)
    core.prepare(round(0.05 + 0.1 * (k + 1), 6))
    return cmd


def test_a_step_computes_the_entries_due_soon_and_takes_the_rest_prepared() -> None:
    core, every = _twins()
    n, fresh = 100, SCENARIO.controller.sequence.fresh_s
    # entries up to fresh_s past the next command's arrival (0.1 s + the 0.2 s downlink)
    last = core.link.fresh_last(0.05, 0.05 + 0.2)
    assert last == round((0.2 + 0.1 + fresh) / 0.1) < n
    for k in range(8):
        prepared = core.link._prepared
        assert (prepared is None) is (k == 0)
        assert prepared is None or prepared.t == round(0.05 + 0.1 * k, 6)
        got, want = _feed(core, k), _feed(every, k)
        # entry 0 and the entries after it up to `last`: the same floats as every entry
        # computed in the step (no command is lost here, so both predict the same state)
        assert (got.v, got.w) == (want.v, want.w)
        assert got.v_next[:last] == want.v_next[:last] and got.w_next[:last] == want.w_next[:last]
        if k == 0:  # nothing was prepared before the first step: all computed in it
            assert got == want
            continue
        # the later ones: those prepared after the step before (quantised on the wire),
        # a prediction one period older, close to the fresh ones
        assert prepared is not None
        for mine, theirs in ((got.v_next, prepared.vs), (got.w_next, prepared.ws)):
            assert mine[last:] == pytest.approx(theirs[last + 1 :], abs=1e-3)
        assert (got.v_next[last:], got.w_next[last:]) != (want.v_next[last:], want.w_next[last:])
        assert got.v_next[last:] == pytest.approx(want.v_next[last:], abs=0.05)
        assert got.w_next[last:] == pytest.approx(want.w_next[last:], abs=0.05)


@pytest.mark.parametrize("change", ["new stop", "controller restart", "another step time"])
def test_a_prepared_sequence_holds_only_for_the_step_path_and_controller_it_was_made_for(
    change: str,
) -> None:
    core, every = _twins()
    for k in range(3):
        _feed(core, k), _feed(every, k)
    assert core.link._prepared is not None
    if change == "new stop":  # the path found unsafe ahead: the speed profile stops sooner
        for c in (core, every):
            assert c.ref is not None
            c.ref.stop_at(30.0)
    elif change == "controller restart":
        for c in (core, every):
            c.link.restart(c.controller)
    k = 4 if change == "another step time" else 3  # a step skipped: prepared for 0.35 s
    assert _feed(core, k) == _feed(every, k)  # every entry computed in the step


def test_a_tail_the_newest_state_lies_on_is_reused_shifted_by_one_period() -> None:
    core, every = _twins(reuse=True)
    last = core.link.fresh_last(0.05, 0.05 + 0.2)
    cmds = [_feed(core, k) for k in range(5)]
    # the estimates lie on the prediction: every tail after the first step is the command
    # just sent, one period on (no rollout after the step)
    assert (core.link.tails_reused, core.link.tails_rolled) == (5, 0)
    for a, b in itertools.pairwise(cmds):
        assert b.v_next[last:-1] == a.v_next[last + 1 :]
        assert b.w_next[last:-1] == a.w_next[last + 1 :]
    # what the vehicle applies before the next command is fresh_s overdue: as before
    for k, got in enumerate(cmds):
        want = _feed(every, k)
        assert (got.v, got.w, got.v_next[:last]) == (want.v, want.w, want.v_next[:last])
        # the rest: close to every entry computed in the step, except that a tail shifted
        # k - 1 times brakes to rest up to k - 1 periods sooner (its stop tail's horizon)
        cruise = 40  # entries before the stop tail: 1.5 m/s / 0.3 m/s^2 = 5 s before the end
        assert got.v_next[last:cruise] == pytest.approx(want.v_next[last:cruise], abs=0.05)
        assert got.w_next[last:] == pytest.approx(want.w_next[last:], abs=0.05)
        slack = 0.3 * 0.1 * max(0, k - 1) + 0.05
        assert all(
            g <= w + slack for g, w in zip(got.v_next[cruise:], want.v_next[cruise:], strict=True)
        )


def test_a_tail_the_newest_state_departs_from_is_rolled_out_afresh() -> None:
    core, _ = _twins(reuse=True)
    for k in range(3):
        _feed(core, k)
    reused, rolled = core.link.tails_reused, core.link.tails_rolled
    # the estimate jumps 0.3 m to the side (a fix pulled it): beyond reuse_tolerance_m
    t = round(0.05 + 0.1 * 3, 6)
    core.deliver(_estimate(t - 0.05, t - 0.02, x=5.0 + 1.2 * (t - 0.05), y=20.3, v=1.2))
    sent = _cmd(core, t)
    core.prepare(round(t + 0.1, 6))
    assert (core.link.tails_reused, core.link.tails_rolled) == (reused, rolled + 1)
    prepared = core.link._prepared
    assert prepared is not None and prepared.age == 0
    last = core.link.fresh_last(t, t + 0.2)
    assert prepared.vs[last:-1] != pytest.approx(sent.v_next[last:], abs=1e-3) or (
        prepared.ws[last:-1] != pytest.approx(sent.w_next[last:], abs=1e-3)
    )


def test_a_reused_tail_is_at_most_reuse_s_old_and_reuse_s_0_rolls_every_tail() -> None:
    core = _core(["controller.sequence.reuse_s=0.3"], downlink_s=0.2)
    ages = []
    for k in range(8):
        _feed(core, k)
        assert core.link._prepared is not None
        ages.append(core.link._prepared.age)
    assert max(ages) == 3 and 0 in ages
    never = _core(["controller.sequence.reuse_s=0"], downlink_s=0.2)
    for k in range(4):
        _feed(never, k)
    assert (never.link.tails_reused, never.link.tails_rolled) == (0, 4)


def test_no_sequence_is_prepared_when_the_next_step_computes_every_entry() -> None:
    for sets in (["controller.sequence.fresh_s=10"], ["controller.sequence.horizon_s=0"]):
        core = _core(sets, downlink_s=0.2)
        _feed(core, 0)
        assert core.link._prepared is None


def _state(ctrl: object) -> dict[str, object]:
    """A controller's mutable state, for comparison (its config objects are shared)."""
    return {k: vars(v) if k == "speed" else v for k, v in vars(ctrl).items()}


# --- the planner's commands --------------------------------------------------------------------


def test_without_sequences_the_commands_are_todays_single_commands() -> None:
    core = _core(["controller.sequence.horizon_s=0"], downlink_s=0.2)
    core.deliver(_estimate(0.0, 0.03, v=0.8))
    cmd = _cmd(core, 0.05)
    assert (cmd.horizon, cmd.step_ms) == (0, 0)
    # version 4's single command, byte for byte but the version
    plain = VelocityCommand(stamp=0.05, v=cmd.v, w=cmd.w, path_id=1, controller="nurbs")
    assert encode(cmd) == encode(plain)
    # computed as before sequences: the controller's own constant-twist compensation over
    # the estimate's age plus the configured downlink delay (no status has come yet)
    assert core.ref is not None
    fresh = make_controller(SCENARIO.controller, LIMITS)
    pose = (5.0, 20.0, 0.0, 0.8, 0.0)
    assert (cmd.v, cmd.w) == fresh.command(0.05, pose, core.ref, 0.05 + 0.2)


def test_a_sequence_covers_the_horizon_and_its_first_entry_is_the_command_for_now() -> None:
    core = _core(downlink_s=0.2)
    core.deliver(_estimate(0.0, 0.03, v=0.8))
    cmd = _cmd(core, 0.05)
    n = round(SCENARIO.controller.sequence.horizon_s / SCENARIO.planner.period_s)
    assert (cmd.horizon, cmd.step_s) == (n, SCENARIO.planner.period_s) == (100, 0.1)
    # the command for now: the controller on the state predicted for now, the estimate
    # carried 50 ms with what the vehicle applies (nothing sent yet: IDLE, braking)
    assert core.ref is not None
    now = MODEL.advance((5.0, 20.0, 0.0, 0.8, 0.0), 0.0, 0.0, 0.05)
    fresh = make_controller(SCENARIO.controller, LIMITS)
    assert (cmd.v, cmd.w) == fresh.command(0.05, now, core.ref)
    # every entry within eq. (11), the speeds within the shared cruise speed
    assert max(cmd.v_next) <= SCENARIO.vehicle.cruise_speed_mps
    assert all(abs(w) <= SCENARIO.vehicle.w_max_rps for w in cmd.w_next)
    # the planner expects it at the vehicle after the configured downlink delay
    assert core.link.timeline.sent[-1].arrival == pytest.approx(0.05 + 0.2)


def test_the_stop_tail_brings_the_vehicle_to_rest_at_the_end_of_the_buffer() -> None:
    core = _core()
    core.deliver(_estimate(0.0, 0.03, v=1.5))
    cmd = _cmd(core, 0.05)
    brake = SCENARIO.vehicle.accel_max_mps2  # the hull's bound
    speeds = (cmd.v, *cmd.v_next)
    assert speeds[-1] == 0.0 and max(speeds) == SCENARIO.vehicle.cruise_speed_mps
    for k, v in enumerate(speeds):  # never faster than it can stop by the end
        assert v <= brake * (10.0 - 0.1 * k) + 1e-3  # (quantised to mm/s on the wire)
    # and without it the buffer ends at cruise speed (HOLD brakes from there, heading held)
    core = _core(["controller.sequence.stop_tail=false"])
    core.deliver(_estimate(0.0, 0.03, v=1.5))
    assert _cmd(core, 0.05).v_next[-1] == SCENARIO.vehicle.cruise_speed_mps


def test_the_downlink_delay_is_the_vehicles_measurement_plus_the_jitter_margin() -> None:
    core = _core(["controller.jitter_margin_k=2"], downlink_s=0.2)
    assert core.link.downlink_s == 0.2  # configured, until the vehicle has measured one
    core.deliver(_status(1.0, 0.9, 0.05, n=0))  # no sample yet
    assert core.link.downlink_s == 0.2
    core.deliver(_status(2.0, 0.9, 0.05))
    assert core.link.downlink_s == pytest.approx(0.9 + 2 * 0.05)
    core.deliver(_status(1.5, 0.1))  # an older status arriving late changes nothing
    assert core.link.downlink_s == pytest.approx(1.0)
    core.deliver(_status(3.0, 1e6))  # absurd: rejected, counted
    assert core.inputs_rejected == {"status.out_of_range": 1}
    assert core.link.downlink_s == pytest.approx(1.0)


def test_a_known_delay_is_no_outage_but_a_silence_is() -> None:
    for delayed in (True, False):
        core = _core()
        if delayed:  # estimates have been arriving a second after their stamp
            for k in range(20):
                core.deliver(_estimate(0.1 * k, 0.1 * k + 1.0))
        core.deliver(_estimate(2.0, 3.0 if delayed else 2.0))
        # 1.9 s old: 0.9 s beyond the measured delay (fresh), or 1.9 s beyond none (stale)
        out = core.step(3.9)
        assert bool(out) is delayed
    # a silence of more than max_estimate_age_s beyond the known delay is an outage
    assert core.step(3.0 + 1.0 + 0.05) == []
    core = _core()
    for k in range(21):
        core.deliver(_estimate(0.1 * k, 0.1 * k + 1.0))
    assert core.step(2.0 + 1.0 + 0.95)  # 0.95 s beyond the second the estimates take
    assert core.step(2.0 + 1.0 + 1.05) == []
    assert core.stale_skips == 1


def test_after_skipped_steps_the_controller_restarts_from_where_the_vehicle_is() -> None:
    # backstepping's virtual reference runs on by the clock: after 3 s without a step, the
    # vehicle stopped on its buffer, it would wait at its 5 m leash ahead, and with the
    # speed capped at the profile it never comes back: the controller restarts instead (the
    # plan holds: no replan)
    core = _core(['controller.kind="backstepping"', "world.start.y_m=14.0"])
    for k in range(30):  # 3 s along y = 14 at 1.5 m/s (clear of the obstacles), 50 ms old
        t = 0.05 + 0.1 * k
        core.deliver(_estimate(t - 0.05, t - 0.02, x=5.0 + 1.5 * (t - 0.05), v=1.5, y=14.0))
        assert core.step(t)
    paths = core.path_id
    for k in range(30, 60):  # 3 s of silence: stale after 1 s, the vehicle on its buffer
        core.step(0.05 + 0.1 * k)
    assert core.stale_skips > 0
    # meanwhile the vehicle ran its buffer out and stopped (the stop tail) 2 m further on
    t = 0.05 + 0.1 * 60
    core.deliver(_estimate(t - 0.05, t - 0.02, x=5.0 + 1.5 * 2.95 + 2.0, y=14.0))
    assert core.step(t) and core.path_id == paths
    e_x, _, _ = core.controller.last_errors  # type: ignore[attr-defined]
    assert abs(e_x) < 0.5  # the reference restarted at the vehicle's projection, not 5 m on
