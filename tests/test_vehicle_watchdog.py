"""Command watchdog: stale / reordered rejection, clamping, HOLD (its ramp, its braking
distance), FAILSAFE and recovery."""

from __future__ import annotations

import math

import pytest
from scipy.integrate import quad

from common.config.vehicle import VehicleConfig, WatchdogConfig
from common.messages import VehicleStatus, VelocityCommand, replace
from common.runtime.model.core import Delivery
from services.vehicle.core import VehicleCore
from services.vehicle.dynamics import PlantParams, drag_n
from services.vehicle.watchdog import Watchdog, _clamped

# a finite HOLD ramp (0.2 m/s^2, the former default), so the ramp's times can be checked
CFG = WatchdogConfig(
    max_command_age_s=1.0, hold_after_s=2.0, failsafe_after_s=5.0, hold_decel_mps2=0.2
)


def _wd() -> Watchdog:
    return Watchdog(CFG, v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5)


def test_rejects_stale_and_reordered_commands() -> None:
    wd = _wd()
    assert wd.command(0.0).mode == "IDLE"
    assert wd.offer(1.0, 0.9, 1.0, 0.1) == "applied"
    # older than the last applied one (overtaken on the network): rejected
    assert wd.offer(1.1, 0.8, 1.5, 0.2) == "out_of_order"
    # age 1.5 s > max_command_age_s = 1.0 s: rejected
    assert wd.offer(3.0, 1.5, 1.5, 0.2) == "stale"
    assert wd.offer(2.0, 2.0, 1.2, 0.0) == "applied"
    # a duplicate (same stamp, arriving while still fresh) is idempotent
    assert wd.offer(2.5, 2.0, 1.2, 0.0) == "applied"
    r = wd.rejections
    assert (r["out_of_order"], r["stale"], wd.rejected, wd.applied) == (1, 1, 2, 3)
    a = wd.command(3.1)
    assert (a.mode, a.v, a.w) == ("RUN", 1.2, 0.0)
    assert math.isclose(a.age_s, 1.1)


def test_clamps_out_of_range_and_rejects_non_finite() -> None:
    wd = _wd()
    assert wd.offer(0.0, 0.0, 50.0, -3.0) == "applied"
    a = wd.command(0.1)
    assert (a.v, a.w, wd.clamped) == (2.0, -0.5, 1)  # eq. (11) bounds, never raw
    assert wd.offer(0.2, 0.2, -1.0, 0.2) == "applied"
    assert (wd.command(0.3).v, wd.clamped) == (0.0, 2)
    assert wd.offer(0.4, 0.4, 1.0, 0.1) == "applied"
    assert wd.clamped == 2  # in range: not counted
    assert wd.offer(0.5, 0.5, math.nan, 0.0) == "non_finite"
    assert wd.offer(0.5, 0.5, 1.0, math.inf) == "non_finite"
    assert wd.rejections["non_finite"] == 2 and wd.command(0.6).v == 1.0


def test_hold_ramp_failsafe_and_recovery_times() -> None:
    # applied command stamped 1.0: RUN before 3.0, HOLD from 3.0 (speed ramps down at
    # 0.2 m/s^2, w = 0), FAILSAFE from 6.0, RUN again on a fresh command
    wd = _wd()
    wd.offer(1.05, 1.0, 1.0, 0.3)
    assert wd.command(2.999).mode == "RUN"
    a = wd.command(3.0)
    assert (a.mode, a.v, a.w) == ("HOLD", 1.0, 0.0)
    assert math.isclose(wd.command(4.0).v, 0.8)
    assert wd.command(5.999).mode == "HOLD"
    f = wd.command(6.0)
    assert (f.mode, f.w) == ("FAILSAFE", 0.0)
    assert math.isclose(f.v, 0.4)
    assert wd.command(20.0).v == 0.0  # ramp ends at zero speed
    assert wd.offer(20.0, 19.9, 1.5, -0.1) == "applied"
    r = wd.command(20.0)
    assert (r.mode, r.v, r.w) == ("RUN", 1.5, -0.1)


def _status(core: VehicleCore, t: float) -> VehicleStatus:
    msg = core.step(t)[1].msg
    assert isinstance(msg, VehicleStatus)
    return msg


def _send(core: VehicleCore, t: float, stamp: float, v: float, w: float) -> None:
    msg = VelocityCommand(stamp=stamp, v=v, w=w, path_id=0)
    core.deliver(Delivery(source="planner", stream="cmd", msg=msg, t=t))


def test_core_hold_and_failsafe_at_the_configured_times() -> None:
    # commands every 0.1 s until stamp 10.0, then silence. Mode at the configured times to
    # within one internal step (10 ms): RUN at 11.99, HOLD at 12.01, FAILSAFE at 15.01;
    # heading frozen in HOLD (|w| < 1e-3 rad/s 3 s after HOLD), the commanded speed ramps
    # at 0.2 m/s^2 (0.4 m/s at 15 s, 0 at 17 s), the vehicle nearly stopped (< 0.05 m/s)
    # by 19.9 s with its heading held (drift < 1e-3 rad); a
    # fresh command at 20 s brings RUN back and the vehicle moves again (> 0.5 m/s at 25 s).
    cfg = VehicleConfig(watchdog=CFG)
    core = VehicleCore(cfg, (0.0, 0.0, 0.0))
    for k in range(101):
        t = 0.1 * k
        _send(core, t, t, 1.0, 0.1)
        core.step(t)
    assert _status(core, 11.99).mode == "RUN"
    s = _status(core, 12.01)
    assert (s.mode, s.w_applied) == ("HOLD", 0.0)
    assert s.v_applied < 1.0 and math.isclose(s.command_age, 2.01)
    assert _status(core, 14.99).mode == "HOLD"
    assert abs(core.pose[4]) < 1e-3
    s = _status(core, 15.01)
    assert s.mode == "FAILSAFE"
    assert math.isclose(s.v_applied, 1.0 - 0.2 * 3.01, abs_tol=0.2 * 0.01 + 1e-9)
    theta_hold = core.pose[2]
    assert _status(core, 19.9).mode == "FAILSAFE"
    assert abs(core.pose[2] - theta_hold) < 1e-3 and core.pose[3] < 0.05
    _send(core, 20.0, 19.95, 1.0, 0.0)
    s = _status(core, 20.05)
    assert (s.mode, s.v_applied) == ("RUN", 1.0)
    _status(core, 25.0)
    assert core.pose[3] > 0.5


def test_core_counts_rejections_and_clamps_in_status() -> None:
    cfg = VehicleConfig(watchdog=CFG)
    core = VehicleCore(cfg, (0.0, 0.0, 0.0))
    _send(core, 1.0, 0.95, 9.0, 0.0)  # applied, clamped to v_max
    _send(core, 1.2, 0.90, 1.0, 0.0)  # older than the last applied: rejected
    # 1.3 s old, beyond max_command_age_s + the delay measured so far (the median of 0.05 s
    # and 0.3 s, 0.175 s): rejected
    _send(core, 2.8, 1.50, 1.0, 0.0)
    s = _status(core, 2.85)
    assert (s.commands_applied, s.commands_rejected, s.commands_clamped) == (1, 2, 1)
    assert s.v_applied == 2.0


def test_watchdog_config_validation() -> None:
    with pytest.raises(ValueError, match="failsafe_after_s"):
        WatchdogConfig(hold_after_s=2.0, failsafe_after_s=2.0)
    with pytest.raises(ValueError, match="hold_after_s"):
        WatchdogConfig(max_command_age_s=3.0, hold_after_s=2.0)
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="hold_decel_mps2"):
            WatchdogConfig(hold_decel_mps2=bad)
    assert WatchdogConfig().hold_decel_mps2 == 0.0  # the default: brake at once


def test_hold_drops_the_speed_command_at_once_by_default() -> None:
    wd = Watchdog(WatchdogConfig(), v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5)
    wd.offer(1.0, 1.0, 1.5, 0.3)
    assert (wd.command(2.999).v, wd.command(2.999).w) == (1.5, 0.3)
    a = wd.command(3.0)  # hold_after_s = 2 s after the stamp
    assert (a.mode, a.v, a.w) == ("HOLD", 0.0, 0.0)
    # with a speed floor (v_min > 0) HOLD keeps that speed: the floor, not zero
    wd = Watchdog(WatchdogConfig(), v_min=0.3, v_max=2.0, w_min=-0.5, w_max=0.5)
    wd.offer(1.0, 1.0, 1.5, 0.3)
    assert (wd.command(3.0).v, wd.command(9.0).mode) == (0.3, "FAILSAFE")


def _blind_run(cfg: VehicleConfig, v0: float) -> tuple[float, float]:
    """Cruise at v0 with commands every 0.1 s up to t = 40 s, then silence: the distance run
    on the last command before HOLD, and the distance from HOLD to standstill."""
    core = VehicleCore(cfg, (0.0, 0.0, 0.0))
    for k in range(401):
        _send(core, 0.1 * k, 0.1 * k, v0, 0.0)
        core.step(0.1 * k)
    x_last = core.pose[0]
    t = 40.0 + cfg.watchdog.hold_after_s
    assert _status(core, t).mode == "HOLD"
    x_hold = core.pose[0]
    while core.pose[3] > 1e-4:
        t += cfg.period_s
        assert t < 80.0, "the vehicle never stopped"
        core.step(t)
    return x_hold - x_last, core.pose[0] - x_hold


def _braking_distance(cfg: VehicleConfig, v0: float) -> float:
    """Oracle: the distance to stop from v0 at the hull's limit, int_0^v0 v / a(v) dv with
    a(v) = min(accel_max, (|T_min| + R(v)) / m_eff): full reverse thrust plus eq. (14) drag."""
    p = PlantParams.from_config(cfg)

    def decel(v: float) -> float:
        return min(p.accel_max, (-p.thrust_min_n + drag_n(v, p)) / p.mass_eff_kg)

    return float(quad(lambda v: v / decel(v), 0.0, v0)[0])


@pytest.mark.parametrize("v0", [1.0, 1.5, 2.0])
def test_hold_stops_within_the_hulls_braking_distance(v0: float) -> None:
    # Defaults: HOLD brakes at the hull's limit (the speed loop at full reverse thrust); the
    # oracle leaves out the speed loop's lag and its unsaturated tail below ~0.14 m/s
    # (measured: 6-7 cm). Measured from 1.5 m/s: 5.42 m, where the 0.2 m/s^2 ramp took 7.28 m.
    cfg = VehicleConfig()
    before, brake = _blind_run(cfg, v0)
    assert before == pytest.approx(v0 * cfg.watchdog.hold_after_s, abs=0.01)
    assert _braking_distance(cfg, v0) <= brake <= _braking_distance(cfg, v0) + 0.1
    _, ramp_brake = _blind_run(VehicleConfig(watchdog=CFG), v0)
    assert brake < 0.8 * ramp_brake


def test_one_command_from_the_far_future_cannot_lock_out_the_later_ones() -> None:
    wd = Watchdog(CFG, v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5, commander="planner")
    assert wd.offer(1.0, 1.0, 1.0, 0.0, "planner") == "applied"
    # a glitching clock or a hostile client: stamped now + 10^6 s
    assert wd.offer(1.1, 1.0e6, 2.0, 0.5, "planner") == "future"
    assert wd.offer(1.2, 1.2 + CFG.max_future_s / 2, 1.1, 0.0, "planner") == "applied"
    for k in range(1, 20):  # every later planner command still goes through
        assert wd.offer(1.5 + k * 0.1, 1.5 + k * 0.1, 1.0, 0.0, "planner") == "applied"
    assert wd.command(3.5).mode == "RUN"


def test_only_the_commanders_commands_count_and_every_rejection_is_counted_by_reason() -> None:
    wd = Watchdog(CFG, v_min=0.0, v_max=2.0, w_min=-0.5, w_max=0.5, commander="planner")
    assert wd.offer(1.0, 1.0, 1.0, 0.0, "rogue") == "wrong_source"
    assert wd.offer(1.0, 1.0, 1.0, 0.0, "") == "wrong_source"
    assert wd.command(1.5).mode == "IDLE"  # nothing applied
    assert wd.offer(1.0, 1.0, 1.0, 0.0, "planner") == "applied"
    assert wd.offer(1.1, 0.5, 1.0, 0.0, "planner") == "out_of_order"
    assert wd.offer(1.1, 9.0, 1.0, 0.0, "planner") == "future"
    assert wd.offer(5.0, 3.0, 1.0, 0.0, "planner") == "stale"
    assert wd.offer(5.0, math.nan, 1.0, 0.0, "planner") == "non_finite"
    assert wd.rejections == {
        "non_finite": 1,
        "wrong_source": 2,
        "future": 1,
        "malformed": 0,
        "too_long": 0,
        "out_of_order": 1,
        "stale": 1,
    }
    assert wd.rejected == 6


def test_the_vehicle_reports_rejections_by_reason_and_logs_each_reason_once_a_second(
    caplog: pytest.LogCaptureFixture,
) -> None:
    core = VehicleCore(VehicleConfig(), (0.0, 0.0, 0.0), commander="planner")
    rogue = VelocityCommand(stamp=0.0, v=2.0, w=0.5, path_id=1, source="monitor")
    with caplog.at_level("WARNING", logger="tidelink.vehicle"):
        for t in [0.01 * k for k in range(50)] + [1.1]:  # 100 Hz for 0.5 s, then once more
            core.deliver(Delivery("planner", "cmd", replace(rogue, stamp=t), t))
    assert len([r for r in caplog.records if "wrong_source" in r.getMessage()]) == 2
    status = [e.msg for e in core.step(1.2) if isinstance(e.msg, VehicleStatus)][0]
    assert status.commands_applied == 0 and status.mode == "IDLE"
    assert status.rejected_by_reason["wrong_source"] == 51
    assert status.commands_rejected == 51


def test_the_clamp_is_min_of_max_entry_by_entry_and_object_by_object() -> None:
    """_clamped writes min(max(x, lo), hi) out in one pass: the same objects as the builtins
    give, for entries inside, below and above the bounds, infinite or NaN, and for bounds the
    wrong way round."""
    nan = math.nan
    xs = (-3.0, -0.5, -0.0, 0.0, 0.25, 0.5, 2.0, math.inf, -math.inf, nan)
    for lo, hi in ((-0.5, 0.5), (0.0, 2.0), (0.5, -0.5), (-math.inf, math.inf), (1.0, 1.0)):
        got = _clamped(xs, lo, hi)
        want = tuple(min(max(x, lo), hi) for x in xs)
        assert len(got) == len(want)
        assert all(g is w for g, w in zip(got, want, strict=True))
