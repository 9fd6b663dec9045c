"""The three tracking controllers in closed loop with the vehicle core (no network)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from common.config.controller import ControllerConfig, ControllerKind
from common.config.vehicle import VehicleConfig
from common.messages import TruthState, VelocityCommand
from common.runtime.model.core import Delivery
from services.control.controllers import Circle, Limits, StraightLine, make_controller
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import path_errors
from services.vehicle.core import VehicleCore

VCFG = VehicleConfig()
LIMITS = Limits.from_vehicle(VCFG)
KINDS: tuple[ControllerKind, ...] = ("nurbs", "backstepping", "fuzzy_pid")


def closed_loop(
    kind: ControllerKind,
    ref: ArcLengthReference,
    start: tuple[float, float, float],
    t_end: float,
    *,
    pose_delay_s: float = 0.0,
    compensate: bool | None = None,
    limits: Limits = LIMITS,
) -> np.ndarray:
    """Rows (t, e_y, v_cmd, w_cmd, v_pose, v, w) at 20 Hz; the controller runs at 10 Hz on
    exact truth. v_pose is the speed of the pose the last command was computed from; v and w
    are the vehicle's true speed and yaw rate.

    With pose_delay_s the controller sees the truth of pose_delay_s ago and is told
    latency_s = pose_delay_s (a delayed estimate, no downlink delay).
    """
    cfg = ControllerConfig(kind=kind)
    if compensate is not None:  # one switch for every controller
        cfg = ControllerConfig(kind=kind, delay_compensation=compensate)
    ctrl = make_controller(cfg, limits)
    core = VehicleCore(VCFG, start)
    lag = round(pose_delay_s / VCFG.period_s)
    poses: list[tuple[float, float, float, float, float]] = []
    rows = []
    s_hint: float | None = None
    v_cmd = w_cmd = v_pose = 0.0
    for k in range(round(t_end / VCFG.period_s) + 1):
        t = k * VCFG.period_s
        truth = core.step(t)[0].msg
        assert isinstance(truth, TruthState)
        poses.append((truth.x, truth.y, truth.theta, truth.v, truth.w))
        if k % 2 == 0:
            pose = poses[max(0, len(poses) - 1 - lag)]
            v_pose = pose[3]
            v_cmd, w_cmd = ctrl.command(t, pose, ref, latency_s=pose_delay_s)
            msg = VelocityCommand(stamp=t, v=v_cmd, w=w_cmd, path_id=0, controller=kind)
            core.deliver(Delivery(source="planner", stream="cmd", msg=msg, t=t))
        s_hint = ref.closest_s(truth.x, truth.y, s_hint)
        e_y, _ = path_errors(truth.x, truth.y, truth.theta, ref, s_hint)
        rows.append((t, e_y, v_cmd, w_cmd, v_pose, truth.v, truth.w))
    return np.array(rows)


def _assert_commands_in_bounds(out: np.ndarray) -> None:
    v, w, v_pose = out[:, 2], out[:, 3], out[:, 4]
    assert np.all((v >= LIMITS.v_min) & (v <= LIMITS.v_max))  # eq. (11)
    assert np.all((w >= LIMITS.w_min) & (w <= LIMITS.w_max))
    # every controller: turning radius >= R_min (eqs. 19-20) at the speed the pose has
    assert np.all(np.abs(w) <= v_pose / LIMITS.r_min + 1e-12)
    # ... as the plant enforces, and the speed never above the path's cruise speed
    assert np.all(np.abs(out[:, 6]) <= out[:, 5] / LIMITS.r_min + 1e-12)
    assert np.all(v <= 1.5)


LINE = StraightLine(x0=0.0, y0=0.0, x1=400.0, y1=0.0, v_ref=1.5)
THIRTY = math.radians(30.0)


@pytest.mark.parametrize("kind", KINDS)
@pytest.mark.parametrize(
    "start",
    [(0.0, 3.0, THIRTY), (0.0, -3.0, -THIRTY), (0.0, 3.0, -THIRTY)],
    ids=["left-heading-away", "right-heading-away", "left-heading-in"],
)
def test_converges_to_a_straight_line(
    kind: ControllerKind, start: tuple[float, float, float]
) -> None:
    # 3 m offset and 30 deg heading error, from rest: |e_y| < 0.2 m over 40..50 s, commands
    # in eq. (11) and R_min (measured from the left: nurbs 1e-6 m, backstepping 0.096 m,
    # fuzzy_pid 0.010 m; backstepping converges the slowest, with a ~8 s time constant: its
    # speed is capped at the profile, so it no longer closes on a reference that ran ahead
    # by speeding past the cruise speed)
    out = closed_loop(kind, LINE, start, 50.0)
    assert np.max(np.abs(out[out[:, 0] >= 40.0, 1])) < 0.2
    _assert_commands_in_bounds(out)


# radius 8 m > R_min = 5 m; start 2 m outside the circle, on its tangent heading
CIRCLE = Circle(cx=0.0, cy=0.0, radius=8.0, phase0=-0.5 * math.pi, ccw=True, turns=3.0)
CIRCLE_RMS_BOUND = {"nurbs": 0.01, "backstepping": 0.02, "fuzzy_pid": 0.05}


@pytest.mark.parametrize("kind", KINDS)
def test_follows_a_circle(kind: ControllerKind) -> None:
    # RMS cross-track over 30..80 s (after the transient) below the per-controller bound:
    # nurbs 0.01 m (measured 1e-5: curvature feed-forward), backstepping 0.02 m (measured
    # 6e-3), fuzzy_pid 0.05 m (measured 0.016: no feed-forward, the integral carries the turn)
    out = closed_loop(kind, CIRCLE, (0.0, -10.0, 0.0), 80.0)
    tail = out[out[:, 0] >= 30.0, 1]
    assert math.sqrt(float(np.mean(tail**2))) < CIRCLE_RMS_BOUND[kind]
    _assert_commands_in_bounds(out)


def test_nurbs_delay_compensation_beats_no_compensation() -> None:
    # the controller sees a 0.5 s old pose. Without compensation the loop settles into a
    # +-0.24 m limit cycle on the line; predicting the pose forward by latency_s = 0.5 s
    # removes it. Bounds: over 20..60 s RMS < 0.01 m with, > 0.1 m without (measured 5e-3
    # and 0.17); over 15..60 s the compensated RMS is below a third of the other (0.044
    # vs 0.173; the first seconds, the approach from 3 m at rest, are alike); on the circle
    # (30..80 s) compensated RMS < 0.01 m and at most a fifth of the uncompensated 0.075 m.
    def rms(out: np.ndarray, t0: float) -> float:
        return math.sqrt(float(np.mean(out[out[:, 0] >= t0, 1] ** 2)))

    start = (0.0, 3.0, THIRTY)
    on = closed_loop("nurbs", LINE, start, 60.0, pose_delay_s=0.5, compensate=True)
    off = closed_loop("nurbs", LINE, start, 60.0, pose_delay_s=0.5, compensate=False)
    assert rms(on, 20.0) < 0.01 and rms(off, 20.0) > 0.1
    assert rms(on, 15.0) < rms(off, 15.0) / 3.0
    c_on = closed_loop("nurbs", CIRCLE, (0.0, -10.0, 0.0), 80.0, pose_delay_s=0.5, compensate=True)
    c_off = closed_loop(
        "nurbs", CIRCLE, (0.0, -10.0, 0.0), 80.0, pose_delay_s=0.5, compensate=False
    )
    assert rms(c_on, 30.0) < 0.01
    assert rms(c_on, 30.0) < 0.2 * rms(c_off, 30.0)
    for out in (on, off, c_on, c_off):
        _assert_commands_in_bounds(out)


class SBend:
    """10 m straight, a quarter turn left and one right on arcs of 6 m (curvature 0.83 / R_min,
    near the plant's limit), 30 m straight: sampled every 1 cm from its curvature profile."""

    v_ref = 1.5

    def __init__(self) -> None:
        ds, quarter = 0.01, 6.0 * math.pi / 2.0
        legs = ((10.0, 0.0), (quarter, 1.0 / 6.0), (quarter, -1.0 / 6.0), (30.0, 0.0))
        self.k = np.concatenate([np.full(round(n / ds), k) for n, k in legs])
        self.s = np.arange(len(self.k)) * ds
        self.th = np.concatenate([[0.0], np.cumsum(self.k[:-1] * ds)])
        self.x = np.concatenate([[0.0], np.cumsum(np.cos(self.th[:-1]) * ds)])
        self.y = np.concatenate([[0.0], np.cumsum(np.sin(self.th[:-1]) * ds)])
        self.length = float(self.s[-1])

    def _i(self, s: float) -> int:
        return int(np.clip(round(s / 0.01), 0, len(self.s) - 1))

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        return float(self.s[int(np.argmin(np.hypot(self.x - x, self.y - y)))])

    def point_at_s(self, s: float) -> tuple[float, float]:
        return float(self.x[self._i(s)]), float(self.y[self._i(s)])

    def heading_at_s(self, s: float) -> float:
        return float(self.th[self._i(s)])

    def curvature_at_s(self, s: float) -> float:
        return float(self.k[self._i(s)])


@pytest.mark.parametrize("kind", ["nurbs", "backstepping"])
def test_a_feed_forward_read_the_yaw_lag_ahead_follows_a_tight_s_bend_closer(
    kind: ControllerKind,
) -> None:
    # the plant's yaw rate follows its command with yaw_tau_s = 0.5 s: a feed-forward read
    # where the vehicle is turns late and wide, one read that much ahead (at the vehicle's
    # speed: controller.yaw_lag_lead) keeps closer to the bends (the fleet's paths near the
    # turning limit were followed 1.2-1.5 m wide without it)
    ref = SBend()
    lead = Limits.from_vehicle(VCFG, yaw_lag_lead=True)
    assert lead.yaw_lead_s == VCFG.yaw_tau_s and LIMITS.yaw_lead_s == 0.0
    worst = {
        name: float(np.max(np.abs(closed_loop(kind, ref, (0.0, 0.0, 0.0), 45.0, limits=lim)[:, 1])))
        for name, lim in (("late", LIMITS), ("ahead", lead))
    }
    # measured: NURBS 1.10 -> 0.18 m; backstepping 1.27 -> 1.20 m (its virtual reference,
    # not its feed-forward, sets how wide it swings)
    assert worst["ahead"] < {"nurbs": 0.3, "backstepping": 1.0}[kind] * worst["late"], worst
