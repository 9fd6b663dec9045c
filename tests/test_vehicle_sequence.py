"""Packet-based predictive commands at the vehicle: the entry for the current time is applied,
the newest sequence wins, the buffer is consumed through silence and HOLD counts from its end,
a known delay is not an outage, hostile sequences are refused and counted."""

from __future__ import annotations

import math

import pytest

from common.config.errors import ConfigValueError
from common.config.vehicle import VehicleConfig, WatchdogConfig
from common.messages import MAX_SEQUENCE_LEN, TruthState, VehicleStatus, VelocityCommand
from common.runtime.model.core import Delivery
from services.vehicle.core import VehicleCore
from services.vehicle.watchdog import Watchdog

# a finite HOLD ramp, so the ramp's start can be told from the last entry's speed
CFG = WatchdogConfig(
    max_command_age_s=1.0, hold_after_s=2.0, failsafe_after_s=5.0, hold_decel_mps2=0.2
)


def _wd(cfg: WatchdogConfig = CFG) -> Watchdog:
    return Watchdog(cfg, v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5)


def _offer(
    wd: Watchdog,
    t: float,
    stamp: float,
    step_s: float,
    vs: tuple[float, ...],
    ws: tuple[float, ...],
) -> str:
    """Offer (vs[0], ws[0]) from `stamp`, then the rest at step_s, delivered at t."""
    return wd.offer(t, stamp, vs[0], ws[0], step_s=step_s, v_next=vs[1:], w_next=ws[1:])


def _vw(wd: Watchdog, t: float) -> tuple[str, float, float]:
    a = wd.command(t)
    return a.mode, a.v, a.w


def test_the_entry_for_the_current_time_is_applied() -> None:
    wd = _wd()
    # (1.0, 0.1) from 1.0, (1.2, 0.2) from 1.5, (1.4, -0.3) from 2.0
    assert wd.offer(1.0, 1.0, 1.0, 0.1, step_s=0.5, v_next=(1.2, 1.4), w_next=(0.2, -0.3)) == (
        "applied"
    )
    assert _vw(wd, 1.0) == _vw(wd, 1.499) == ("RUN", 1.0, 0.1)
    assert _vw(wd, 1.5) == _vw(wd, 1.999) == ("RUN", 1.2, 0.2)
    assert _vw(wd, 2.0) == _vw(wd, 3.999) == ("RUN", 1.4, -0.3)
    # the age is that of the entry in force
    assert math.isclose(wd.command(1.7).age_s, 0.2) and math.isclose(wd.command(3.0).age_s, 1.0)
    # each entry is clamped to the eq. (11) bounds, and the command counted once as clamped
    assert wd.offer(1.1, 1.1, 1.0, 0.1, step_s=0.5, v_next=(9.0,), w_next=(-3.0,)) == "applied"
    assert (_vw(wd, 1.6), wd.clamped) == (("RUN", 2.0, -0.5), 1)


def test_a_newer_sequence_replaces_an_older_one_and_a_late_older_one_is_ignored() -> None:
    wd = _wd()
    assert wd.offer(1.0, 1.0, 1.0, 0.0, step_s=0.5, v_next=(1.1, 1.2), w_next=(0.1, 0.2)) == (
        "applied"
    )
    assert wd.offer(1.3, 1.25, 0.5, 0.0, step_s=0.5, v_next=(0.6,), w_next=(-0.1,)) == "applied"
    newer = wd.schedule
    assert _vw(wd, 1.6) == ("RUN", 0.5, 0.0)  # the older one said (1.1, 0.1) from 1.5
    assert _vw(wd, 1.75) == ("RUN", 0.6, -0.1)
    # the older one arriving again, late (a reordered copy): ignored, counted
    assert wd.offer(1.4, 1.0, 1.0, 0.0, step_s=0.5, v_next=(1.1, 1.2), w_next=(0.1, 0.2)) == (
        "out_of_order"
    )
    assert wd.schedule is newer and wd.rejections["out_of_order"] == 1
    # a duplicate of the one in force is idempotent: the same schedule, value for value
    assert wd.offer(1.45, 1.25, 0.5, 0.0, step_s=0.5, v_next=(0.6,), w_next=(-0.1,)) == "applied"
    assert wd.schedule == newer


def test_an_exhausted_buffer_holds_at_its_end_plus_hold_after_s_then_fails_safe() -> None:
    # entries from 1.0, 1.5, ..., 3.0 (t_last = 3.0): RUN on the last entry until
    # t_last + hold_after_s = 5.0, HOLD from there (ramp from the last entry's speed), FAILSAFE
    # from t_last + failsafe_after_s = 8.0, however long ago the command arrived
    wd = _wd()
    v_next, w_next = (1.1, 1.2, 1.3, 1.4), (0.1, 0.0, -0.1, -0.2)
    assert wd.offer(1.0, 1.0, 1.0, 0.0, step_s=0.5, v_next=v_next, w_next=w_next) == "applied"
    assert _vw(wd, 4.999) == ("RUN", 1.4, -0.2)
    assert _vw(wd, 5.0) == ("HOLD", 1.4, 0.0)
    assert wd.command(6.0).v == pytest.approx(1.2)
    assert wd.command(7.999).mode == "HOLD"
    assert (wd.command(8.0).mode, wd.command(8.0).age_s) == ("FAILSAFE", 5.0)
    # a single command is the case n = 0: t_last is its stamp, as before sequences existed
    wd = _wd()
    wd.offer(1.0, 1.0, 1.4, -0.2)
    assert (_vw(wd, 2.999), _vw(wd, 3.0), wd.command(6.0).mode) == (
        ("RUN", 1.4, -0.2),
        ("HOLD", 1.4, 0.0),
        "FAILSAFE",
    )


def test_a_sequence_stamped_long_ago_is_fresh_while_its_entries_reach_now() -> None:
    # the run's first command, delivered 1.5 s after its stamp (beyond max_command_age_s,
    # with no delay measured yet): its entries run to t_last = 2.0, so it drives, from the
    # entry for now
    vs, ws = (1.0, 1.1, 1.2, 1.3, 1.4), (0.0,) * 5
    wd = _wd()
    assert _offer(wd, 1.5, 0.0, 0.5, vs, ws) == "applied"
    assert _vw(wd, 1.5) == ("RUN", 1.3, 0.0)
    # all its entries more than max_command_age_s in the past (no delay measured): useless
    assert _offer(_wd(), 3.01, 0.0, 0.5, vs, ws) == "stale"
    assert _offer(_wd(), 2.99, 0.0, 0.5, vs, ws) == "applied"
    # with a delay measured (1.75 s, the median over the commands before) that much later;
    # the first command 1.75 s late is stale (no delay known yet), the next ones are not
    for t_now, verdict in ((4.7, "applied"), (4.8, "stale")):  # 2.7 s, 2.8 s vs 1.0 + 1.75
        wd = _wd()
        got = [_offer(wd, 0.75 + 0.1 * k, 0.1 * k - 1.0, 0.5, vs[:1], ws[:1]) for k in range(3)]
        assert got == ["stale", "applied", "applied"]
        assert wd.delay.delay_s == pytest.approx(1.75)
        assert _offer(wd, t_now, 0.0, 0.5, vs, ws) == verdict


def test_hostile_sequences_are_refused_counted_and_not_measured() -> None:
    wd = _wd(WatchdogConfig(max_sequence_len=50, max_horizon_s=4.0))
    ones, zeros = (1.0,) * 4, (0.0,) * 4
    cases: list[tuple[float, tuple[float, ...], tuple[float, ...], str]] = [
        (0.1, ones, (0.0, 0.0, math.nan, 0.0), "non_finite"),
        (0.1, (1.0, 1.0, math.inf, 1.0), zeros, "non_finite"),
        (math.nan, ones, zeros, "non_finite"),
        (0.0, ones, zeros, "malformed"),
        (-0.1, ones, zeros, "malformed"),
        (0.1, ones, zeros[:2], "malformed"),  # lengths differ
        (0.01, (1.0,) * 52, (0.0,) * 52, "too_long"),  # 51 future entries
        (0.1, (1.0,) * 42, (0.0,) * 42, "too_long"),  # 41 x 0.1 s = 4.1 s
        (0.1, (1.0,) * 10**6, (0.0,) * 10**6, "too_long"),
    ]
    # (entry times are stamp + k * step_s: they cannot be out of order by construction)
    for step_s, vs, ws, why in cases:
        assert _offer(wd, 1.0, 1.0, step_s, vs, ws) == why
    assert wd.rejections == {
        "non_finite": 3,
        "wrong_source": 0,
        "future": 0,
        "malformed": 3,
        "too_long": 3,
        "out_of_order": 0,
        "stale": 0,
    }
    assert wd.command(1.5).mode == "IDLE" and wd.delay.count == 0
    assert _offer(wd, 1.0, 1.0, 0.1, ones, zeros) == "applied"
    assert wd.delay.count == 1


def test_the_vehicles_sequence_bounds_are_validated() -> None:
    for bad in (-1, MAX_SEQUENCE_LEN + 1):
        with pytest.raises(ConfigValueError, match="max_sequence_len"):
            WatchdogConfig(max_sequence_len=bad)
    for bad_s in (0.0, -1.0, math.nan, math.inf):
        with pytest.raises(ConfigValueError, match="max_horizon_s"):
            WatchdogConfig(max_horizon_s=bad_s)
    with pytest.raises(ConfigValueError, match="delay_window"):
        WatchdogConfig(delay_window=0)


# -- at the core -------------------------------------------------------------------------------


def _deliver(core: VehicleCore, t: float, msg: VelocityCommand) -> None:
    core.deliver(Delivery(source="planner", stream="cmd", msg=msg, t=t))


def _status(core: VehicleCore, t: float) -> VehicleStatus:
    msg = core.step(t)[1].msg
    assert isinstance(msg, VehicleStatus)
    return msg


def _truth(core: VehicleCore, t: float) -> tuple[float, ...]:
    truth, status = (e.msg for e in core.step(t))
    assert isinstance(truth, TruthState) and isinstance(status, VehicleStatus)
    return truth.x, truth.y, truth.theta, truth.v, truth.w, status.v_applied, status.command_age


@pytest.mark.parametrize("step_s", [0.25, 0.123])  # on the 10 ms grid, and inside its cells
def test_a_sequence_drives_the_plant_exactly_as_its_entries_sent_one_by_one(step_s: float) -> None:
    # the oracle: entry k as a single command, delivered at its start time stamp + k * step_s.
    # Same splits of the RK4 cells, same values, same HOLD: bit-identical, HOLD included
    n = 30
    v_next = tuple(1.0 + 0.5 * math.sin(0.3 * k) for k in range(1, n + 1))
    w_next = tuple(0.4 * math.cos(0.2 * k) for k in range(1, n + 1))
    seq = VelocityCommand.predictive(
        stamp=1.0, v=1.0, w=0.4, path_id=1, step_s=step_s, v_next=v_next, w_next=w_next
    )
    vs, ws = (seq.v, *seq.v_next), (seq.w, *seq.w_next)  # as quantised for the wire
    cfg = VehicleConfig()
    a, b = (VehicleCore(cfg, (0.0, 0.0, 0.0)) for _ in range(2))
    starts = [1.0 + k * step_s for k in range(n + 1)]
    rows_a, rows_b = [], []
    for i in range(400):
        t = 0.05 * i
        while starts and starts[0] <= t:
            k = n + 1 - len(starts)
            t_k = starts.pop(0)
            if k == 0:
                _deliver(a, t_k, seq)
            _deliver(b, t_k, VelocityCommand(stamp=t_k, v=vs[k], w=ws[k], path_id=1))
        rows_a.append(_truth(a, t))
        rows_b.append(_truth(b, t))
    assert rows_a == rows_b
    assert _status(a, 20.0).mode == "FAILSAFE"  # t_last + 5 s = 1 + 30 step + 5 < 20


def _run(
    deliveries: list[tuple[float, VelocityCommand]], t_end: float
) -> tuple[VehicleCore, list[VehicleStatus]]:
    """Deliver each (t, command) in time order; a status every 0.05 s up to t_end."""
    core = VehicleCore(VehicleConfig(), (0.0, 0.0, 0.0))
    todo = sorted(deliveries, key=lambda d: d[0])
    statuses = []
    for i in range(round(t_end / 0.05) + 1):
        t = 0.05 * i
        while todo and todo[0][0] <= t:
            _deliver(core, *todo.pop(0))
        statuses.append(_status(core, t))
    return core, statuses


def _stream(n_cmds: int, horizon: int) -> list[VelocityCommand]:
    return [
        VelocityCommand.predictive(
            stamp=0.1 * k,
            v=1.5,
            w=0.0,
            path_id=1,
            step_s=0.1 if horizon else 0.0,
            v_next=(1.5,) * horizon,
            w_next=(0.0,) * horizon,
        )
        for k in range(n_cmds)
    ]


def test_a_sequence_delivered_a_second_after_its_stamp_drives_the_vehicle() -> None:
    # 1.0 s one-way delay, sequences of 2 s: no rejection at all, RUN from the first arrival
    core, statuses = _run([(m.stamp + 1.0, m) for m in _stream(200, 20)], 22.0)
    after = [s for s in statuses if s.stamp >= 1.05]
    assert all(s.mode == "RUN" for s in after)
    assert after[-1].commands_rejected == 0 and after[-1].commands_applied == 200
    assert core.pose[3] > 1.4  # at cruise
    # the vehicle measured the delay: 1.0 s, no jitter
    assert after[-1].delay_s == pytest.approx(1.0, abs=1e-9)
    assert after[-1].delay_jitter_s == pytest.approx(0.0, abs=1e-9)
    assert after[-1].delay_samples == 200


def test_a_known_delay_beyond_max_command_age_is_not_an_outage_even_for_single_commands() -> None:
    # single commands 1.5 s late: only the first is stale (no delay known yet); from then on
    # staleness is age beyond the measured 1.5 s, and each command drives for the 0.5 s left
    # of its hold_after_s, while the next arrives every 0.1 s
    core, statuses = _run([(m.stamp + 1.5, m) for m in _stream(200, 0)], 22.0)
    last = statuses[-1]
    assert last.rejected_by_reason["stale"] == 1 and last.commands_applied == 199
    assert all(s.mode == "RUN" for s in statuses if 1.65 <= s.stamp <= 21.5)
    assert core.pose[3] > 1.4


def test_the_buffer_is_consumed_through_silence_and_hold_comes_from_its_end() -> None:
    # one sequence of 3 s (30 entries at 0.1 s), then nothing: the vehicle follows its entries
    # (a turn from 2.0 s on), holds the last one for hold_after_s and then brakes
    v_next = (1.5,) * 30
    w_next = tuple(0.0 if k < 20 else 0.2 for k in range(1, 31))
    seq = VelocityCommand.predictive(
        stamp=0.0, v=1.5, w=0.0, path_id=1, step_s=0.1, v_next=v_next, w_next=w_next
    )
    core = VehicleCore(VehicleConfig(), (0.0, 0.0, 0.0))
    _deliver(core, 0.2, seq)
    s = _status(core, 1.95)
    assert (s.mode, s.w_applied) == ("RUN", 0.0)
    s = _status(core, 2.05)
    assert (s.mode, s.w_applied) == ("RUN", 0.2)
    assert _status(core, 4.99).mode == "RUN"  # t_last + hold_after_s = 3.0 + 2.0
    s = _status(core, 5.01)
    assert (s.mode, s.v_applied, s.w_applied) == ("HOLD", 0.0, 0.0)
    assert s.command_age == pytest.approx(2.01)  # the last entry's age
    assert _status(core, 7.99).mode == "HOLD"
    assert _status(core, 8.01).mode == "FAILSAFE"


def test_the_measured_delay_shrugs_off_one_outlier() -> None:
    # 0.5 s delay but one command 3 s late (overtaken by then: also out of order). The
    # median and the MAD jitter do not move; a mean would have moved by 2.5 s / 31 = 81 ms
    make = _stream(100, 10)
    late = [(m.stamp + (3.0 if k == 50 else 0.5), m) for k, m in enumerate(make)]
    _, statuses = _run(late, 10.6)
    s = next(s for s in statuses if s.stamp >= 8.0)  # just after the outlier: in the window
    assert s.rejected_by_reason["out_of_order"] == 1
    assert s.delay_samples == sum(1 for t, _ in late if t <= s.stamp)
    assert s.delay_s == pytest.approx(0.5, abs=1e-9)
    assert s.delay_jitter_s == pytest.approx(0.0, abs=1e-9)
    assert statuses[-1].delay_samples == 100
