"""The estimator core: fuses delayed navigation (fixes, or odometry and USBL/LBL fixes) and
obstacle scans; publishes the state, the current and the tracks."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from typing import Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from common.config.estimator import EstimatorConfig
from common.config.sensor import SensorConfig
from common.config.world import AreaConfig
from common.guard import Plausibility, RateLimitedLog, Reason, first_reason
from common.guard.rejects import warn_rejected
from common.messages import (
    NavFix,
    ObstacleDetections,
    ObstacleTracks,
    Odometry,
    PositionFix,
    StateEstimate,
)
from common.runtime.model.core import Delivery, Emit
from common.scalar import wrap_angle
from services.estimator.gate import ChiSquareGate
from services.estimator.health import healthy
from services.estimator.measurements import (
    KINDS,
    NavMeasurement,
    Observation,
    fix_noise,
    of_fix,
    of_odometry,
    of_position,
)
from services.estimator.prefilter import NavPrefilter
from services.estimator.replay import ReplayBuffer
from services.estimator.tracks import ObstacleTracker, TrackerState
from services.estimator.unicycle import BIAS, CURRENT, DIM_X, POSE, SWAY
from services.estimator.vehicle_filter import make_vehicle_filter

FloatArray = NDArray[np.float64]

log = logging.getLogger("tidelink.estimator")

M = TypeVar("M", NavMeasurement, ObstacleDetections)

# No prediction spans more than this: a fix after a longer silence restarts the filter from
# itself (the old belief says nothing after so long), and a step this long after the last
# fix publishes the belief predicted this far (its covariance already says "lost").
MAX_PREDICT_S = 60.0
# Work per step, however many measurements arrive between two steps (a flood, a replay
# storm): fixes fused and detections fused (tens and hundreds of microseconds each), replays
# included. A normal run fuses one fix and a few detections per step; a measurement beyond
# the budget is rejected (counted as over_budget) instead of stalling the publish loop.
FIX_BUDGET = 256
DETECTION_BUDGET = 64
# Measurements kept for out-of-sequence fusion (10 Hz fixes over history_s = 2 s are 20).
MAX_BUFFERED = 256
# The configured start pose is the vehicle's pose when the mission starts. An estimator started
# (or restarted) mid-mission gets a first fix the start pose cannot explain: its position is
# outside this chi-square gate (2 dof) of the start belief plus the fix's noise, and the
# filter starts from the fix. Fusing the two instead put a restarted estimator's belief
# halfway between the start and the vehicle (26 m off in a chaos case).
START_GATE = ChiSquareGate(0.9999)
# What the filters' linear algebra raises on a degenerate belief (numpy's LinAlgError is a
# ValueError, like scipy's refusal of non-finite input; overflows are ArithmeticErrors).
NUMERIC_ERRORS = (ArithmeticError, ValueError)


@dataclass(frozen=True, kw_only=True, slots=True)
class VehicleBelief:
    """The vehicle Gaussian (x, P) at `stamp` (None before the first measurement) + pre-filter
    memory, how many times the filter was restarted on the way here, and the position fixes
    gated out (in all, and in a row since the last one fused)."""

    x: FloatArray  # (9,): [x, y, theta, v, w, cx, cy, b, vs]
    P: FloatArray  # (9, 9)
    stamp: float | None
    prefilter: NavPrefilter  # never mutated once stored: fusing works on a copy
    resets: int = 0
    fixes_gated: int = 0
    gated_in_row: int = 0
    # the last gated fix: (stamp, its x, y, the belief's x, y then)
    last_gated: tuple[float, float, float, float, float] | None = None
    located: bool = False  # a position measurement has been fused (or the start explained)


class EstimatorCore:
    """Vehicle EKF/UKF over (prefiltered) fixes and per-id obstacle tracks, all fused at their
    sampling stamps with roll-back for late arrivals; outputs are predicted to the step time
    (the state estimate says how far past its newest fix: predicted_s).

    Every input is judged first (common.guard): a stamp from the future or from long ago, a
    position outside the world, a speed or noise figure no sensor gives, a scan of more
    obstacles than a message may carry, or work beyond the step's budget is rejected,
    counted by reason (`inputs_rejected`) and logged once per reason per mission second. A
    filter that diverges (non-finite, exploding, or its linear algebra fails) restarts from
    the fix being fused (`resets`), so every output is finite.
    """

    def __init__(
        self,
        cfg: EstimatorConfig,
        start: tuple[float, float, float],
        *,
        area: AreaConfig | None = None,
        start_speed_mps: float = 0.0,
        sonar: SensorConfig | None = None,
    ) -> None:
        self.cfg = cfg
        self._filter = make_vehicle_filter(cfg)
        self._tracker = ObstacleTracker(cfg, sonar)
        self._judge = Plausibility.of_area(area if area is not None else AreaConfig())
        self._rejects = RateLimitedLog(log)
        x0 = np.zeros(DIM_X)
        x0[:4] = start[0], start[1], wrap_angle(start[2]), start_speed_mps
        c0 = cfg.init_std_current_mps
        std0 = [cfg.init_std_xy_m, cfg.init_std_xy_m, cfg.init_std_theta_rad, cfg.init_std_v_mps]
        std0 += [cfg.init_std_w_rps, c0, c0, cfg.init_std_heading_bias_rad, cfg.sway_std_mps]
        P0 = np.diag(np.square(std0))
        prefilter = NavPrefilter(cfg.prefilter, cfg.mean_window, cfg.lag_time_constant_s)
        belief = VehicleBelief(x=x0, P=P0, stamp=None, prefilter=prefilter)
        self.nav: ReplayBuffer[NavMeasurement, VehicleBelief] = ReplayBuffer(
            belief, self._fuse, cfg.history_s, max_entries=MAX_BUFFERED
        )
        self.scans: ReplayBuffer[ObstacleDetections, TrackerState] = ReplayBuffer(
            TrackerState(tracks={}),
            self._tracker.fuse,
            cfg.history_s,
            max_entries=MAX_BUFFERED,
            weight=lambda m: max(1, len(m.detections)),
        )
        self._fix_gate = ChiSquareGate(cfg.fix_gate_probability)
        self._spent = {"nav": 0, "obstacles": 0}  # work since the last step, per budget

    # -- fusion (pure functions of the belief and the measurement: replays repeat them) --------
    def _fuse(self, b: VehicleBelief, m: NavMeasurement) -> VehicleBelief:
        """The belief after one navigation measurement of any kind, at its stamp."""
        if isinstance(m, NavFix):
            return self._fuse_fix(b, m)
        if b.stamp is not None and m.stamp - b.stamp > MAX_PREDICT_S:
            b = self._lost(b)
        if isinstance(m, PositionFix):
            return self._fuse_position(b, m)
        fused = self._update(b, m.stamp, of_odometry(m), b.prefilter, locates=False)
        return fused if fused is not None else self._lost(b)

    def _update(
        self,
        b: VehicleBelief,
        stamp: float,
        obs: Observation,
        prefilter: NavPrefilter,
        *,
        locates: bool = True,
    ) -> VehicleBelief | None:
        """b predicted to `stamp` and updated with obs (`locates`: it measures the position);
        None if the filter failed."""
        dt = 0.0 if b.stamp is None else stamp - b.stamp
        try:
            x, P = self._filter.predict(b.x, b.P, dt)
            x, P = self._filter.update(x, P, obs)
        except NUMERIC_ERRORS:  # e.g. a UKF covariance no longer positive definite
            return None
        if not healthy(x, P):
            return None
        return VehicleBelief(
            x=x,
            P=P,
            stamp=stamp,
            prefilter=prefilter,
            resets=b.resets,
            fixes_gated=b.fixes_gated,
            # a row of gated fixes ends with a fix fused, not with dead reckoning between them
            gated_in_row=0 if locates else b.gated_in_row,
            last_gated=None if locates else b.last_gated,
            located=b.located or locates,
        )

    def _fuse_fix(self, b: VehicleBelief, fix: NavFix) -> VehicleBelief:
        if b.stamp is not None and fix.stamp - b.stamp > MAX_PREDICT_S:
            return self._restart(b, fix)
        if not b.located and not self._start_explains(b, fix.x, fix.y, fix.std_xy):
            return self._restart(b, fix)
        prefilter = b.prefilter.copy()
        z = prefilter.apply(fix.stamp, np.array([fix.x, fix.y, fix.heading, fix.speed]))
        fused = self._update(b, fix.stamp, of_fix(fix, z), prefilter)
        # diverged: the fix (plausible, judged) is the better belief
        return fused if fused is not None else self._restart(b, fix)

    def _fuse_position(self, b: VehicleBelief, fix: PositionFix) -> VehicleBelief:
        """A USBL/LBL fix, gated on its innovation: an outlier is not fused. When two gated
        fixes in a row agree with each other (their difference is the motion the filter
        dead-reckoned between them, within the gate), or fix_gate_reset_after are gated in
        a row, the filter is the one that is lost: it is moved to the fix (`_relocate`)."""
        obs = of_position(fix)
        x, P = b.x, b.P
        if b.stamp is not None:
            try:
                x, P = self._filter.predict(b.x, b.P, fix.stamp - b.stamp)
            except NUMERIC_ERRORS:
                return self._relocate(b, fix, obs)
        y, S = obs.innovation(x, P)
        if self._fix_gate.accepts(y, S):
            fused = self._update(b, fix.stamp, obs, b.prefilter)
            return fused if fused is not None else self._relocate(b, fix, obs)
        # an outlier, or the belief is off: compare with the last gated fix
        here = (fix.stamp, fix.x, fix.y, float(x[0]), float(x[1]))
        gated = replace(
            b, fixes_gated=b.fixes_gated + 1, gated_in_row=b.gated_in_row + 1, last_gated=here
        )
        if gated.gated_in_row >= self.cfg.fix_gate_reset_after or self._agrees(b, here, obs):
            return self._relocate(gated, fix, obs)
        return gated

    def _agrees(
        self, b: VehicleBelief, here: tuple[float, float, float, float, float], obs: Observation
    ) -> bool:
        """Whether a gated fix agrees with the last one gated in a row (the same offset from
        the belief, within the gate on twice the fix noise)."""
        last = b.last_gated
        if last is None or b.gated_in_row == 0:
            return False
        d = np.array(
            [(here[1] - here[3]) - (last[1] - last[3]), (here[2] - here[4]) - (last[2] - last[4])]
        )
        return self._fix_gate.accepts(d, 2.0 * obs.R)

    def _relocate(self, b: VehicleBelief, fix: PositionFix, obs: Observation) -> VehicleBelief:
        """The belief moved to a position fix (its noise as the position's covariance, the
        rest predicted to its stamp): the start could not explain it, or the filter lost it."""
        x, P = self._filter.predict(b.x, b.P, 0.0 if b.stamp is None else fix.stamp - b.stamp)
        if not healthy(x, P):
            x, P = b.x.copy(), b.P.copy()
        x[:2] = obs.z
        P[:2, :] = 0.0
        P[:, :2] = 0.0
        P[:2, :2] = obs.R
        return replace(
            b,
            x=x,
            P=P,
            stamp=fix.stamp if b.stamp is None else max(b.stamp, fix.stamp),
            resets=b.resets + 1,
            gated_in_row=0,
            last_gated=None,
            located=True,
        )

    def _lost(self, b: VehicleBelief) -> VehicleBelief:
        """The belief after a long silence or a failed update with no position to restart
        from: kept, with the initial uncertainty added (the next fix locates it again)."""
        cfg = self.cfg
        stds = [cfg.init_std_xy_m * 10.0] * 2 + [cfg.init_std_theta_rad, cfg.init_std_v_mps]
        stds += [cfg.init_std_w_rps] + [cfg.init_std_current_mps] * 2
        stds += [cfg.init_std_heading_bias_rad, cfg.sway_std_mps]
        P = np.diag(np.square(stds))
        P[BIAS, BIAS] = b.P[BIAS, BIAS]  # a silence says nothing new of the sensor's bias
        return replace(b, P=P, resets=b.resets + 1, located=False)

    def _start_explains(self, b: VehicleBelief, x: float, y: float, std_xy: float) -> bool:
        """Whether the start belief and the first position measured agree (START_GATE)."""
        d = np.array([x - b.x[0], y - b.x[1]])
        return START_GATE.accepts(d, b.P[:2, :2] + np.eye(2) * max(std_xy * std_xy, 1e-12))

    def _restart(self, b: VehicleBelief, fix: NavFix) -> VehicleBelief:
        """The belief of this fix alone (yaw rate and current unknown): after a long silence
        or when the filter diverged. Fresh pre-filter memory: the old window is from before
        the gap."""
        cfg = self.cfg
        prefilter = NavPrefilter(cfg.prefilter, cfg.mean_window, cfg.lag_time_constant_s)
        z = prefilter.apply(fix.stamp, np.array([fix.x, fix.y, fix.heading, fix.speed]))
        x = np.zeros(DIM_X)
        x[:4] = z[0], z[1], wrap_angle(float(z[2])), z[3]
        P = np.zeros((DIM_X, DIM_X))
        P[:4, :4] = fix_noise(fix)
        P[4, 4] = cfg.init_std_w_rps**2
        P[CURRENT, CURRENT] = np.eye(2) * cfg.init_std_current_mps**2
        P[SWAY, SWAY] = cfg.sway_std_mps**2
        x[BIAS], P[BIAS, BIAS] = b.x[BIAS], b.P[BIAS, BIAS]  # the sensor's, kept
        return VehicleBelief(
            x=x,
            P=P,
            stamp=fix.stamp,
            prefilter=prefilter,
            resets=b.resets + 1,
            fixes_gated=b.fixes_gated,
            located=True,
        )

    # -- ServiceCore ---------------------------------------------------------------------------
    def deliver(self, d: Delivery) -> list[Emit]:
        msg = d.msg
        if isinstance(msg, NavFix):
            self._offer_nav("nav", msg, d.t, self._judge_fix(msg, d.t))
        elif isinstance(msg, Odometry):
            self._offer_nav("odometry", msg, d.t, self._judge_odometry(msg, d.t))
        elif isinstance(msg, PositionFix):
            self._offer_nav("fix", msg, d.t, self._judge_position(msg, d.t))
        elif isinstance(msg, ObstacleDetections):
            why = self._judge_scan(msg, d.t)
            self._offer("obstacles", self.scans, msg, d.t, why, DETECTION_BUDGET)
        return []

    def _offer_nav(self, stream: str, msg: NavMeasurement, t: float, why: Reason | None) -> None:
        # one buffer for every kind: they update the same belief, in stamp order; the key's
        # seq tells kinds apart (each stream numbers its own messages)
        key = msg.seq * len(KINDS) + KINDS[type(msg)]
        self._offer("nav", self.nav, msg, t, why, FIX_BUDGET, key=key, stream=stream)

    def _offer(
        self,
        budget_key: str,
        buffer: ReplayBuffer[M, Any],
        msg: M,
        t: float,
        why: Reason | str | None,
        budget: int,
        *,
        key: int | None = None,
        stream: str | None = None,
    ) -> None:
        """Fuse a judged measurement within the step's budget, or count and log why not."""
        seq = msg.seq if key is None else key
        if why is None:
            cost = buffer.cost(msg, msg.stamp, seq)
            if self._spent[budget_key] + cost > budget:
                why = "over_budget"
            else:
                self._spent[budget_key] += cost
                buffer.add(msg, msg.stamp, seq)
                return
        warn_rejected(self._rejects, stream or budget_key, why, t, msg)

    def _judge_fix(self, fix: NavFix, now: float) -> Reason | None:
        j = self._judge
        return first_reason(
            j.stamp(fix.stamp, now),
            j.position(fix.x, fix.y),
            j.angle(fix.heading),
            j.speed(fix.speed, fix.std_speed),
            j.length(fix.std_xy),
            j.angle_std(fix.std_heading),
        )

    def _judge_odometry(self, m: Odometry, now: float) -> Reason | None:
        j = self._judge
        return first_reason(
            j.stamp(m.stamp, now),
            j.angle(m.heading),
            j.rate(m.yaw_rate, m.std_yaw_rate),
            j.speed(m.water_speed, m.std_water_speed, m.u_ground, m.v_ground, m.std_velocity),
            j.angle_std(m.std_heading),
        )

    def _judge_position(self, m: PositionFix, now: float) -> Reason | None:
        j = self._judge
        return first_reason(j.stamp(m.stamp, now), j.position(m.x, m.y), j.length(m.std_xy))

    def _judge_scan(self, scan: ObstacleDetections, now: float) -> Reason | None:
        j = self._judge
        why = first_reason(j.stamp(scan.stamp, now), j.items(len(scan.detections)))
        for det in scan.detections:
            if why is not None:
                break
            why = first_reason(
                j.position(det.x, det.y), j.length(det.radius, det.std_xy, det.std_radius)
            )
        return why

    def belief_at(self, t: float) -> tuple[FloatArray, FloatArray, float]:
        """The vehicle belief (x, P) predicted from the last fused fix to time t (at most
        MAX_PREDICT_S ahead; the fused belief itself if the prediction is not finite), and
        how far it was predicted (s). Before the first fix, the belief is the start pose as it
        was at mission time 0: an estimator started mid-mission says how old that is, so a
        planner takes it as stale (and waits for a fix) rather than as the vehicle's pose."""
        b = self.nav.state
        dt = max(0.0, min(t - (b.stamp if b.stamp is not None else 0.0), MAX_PREDICT_S))
        try:
            x, P = self._filter.predict(b.x, b.P, dt)
        except NUMERIC_ERRORS:
            return b.x.copy(), b.P.copy(), 0.0
        if not healthy(x, P):
            return b.x.copy(), b.P.copy(), 0.0
        return x, P, dt

    def step(self, t: float) -> list[Emit]:
        self._spent = dict.fromkeys(self._spent, 0)
        x, P, predicted_s = self.belief_at(t)
        state = StateEstimate(
            stamp=t,
            predicted_s=predicted_s,
            x=float(x[0]),
            y=float(x[1]),
            theta=float(x[2]),
            v=float(x[3]),
            w=float(x[4]),
            covariance=tuple(P[POSE, POSE].ravel().tolist()),  # Python floats, row-major
            current_x=float(x[5]),
            current_y=float(x[6]),
            current_std=math.sqrt(max(0.0, 0.5 * (P[5, 5] + P[6, 6]))),
            sway=float(x[SWAY]),
            sway_std=math.sqrt(max(0.0, P[SWAY, SWAY])),
        )
        pose = (state.x, state.y, state.theta)  # whence the sonar looks (tracks.py coasting)
        tracks = ObstacleTracks(stamp=t, tracks=self._tracker.tracks_at(self.scans.state, t, pose))
        return [Emit(stream="state", msg=state), Emit(stream="tracks", msg=tracks)]

    # -- what the runtime reports --------------------------------------------------------------
    @property
    def inputs_rejected(self) -> dict[str, int]:
        """Inputs rejected, by '<stream>.<reason>': implausible, over the step's budget, too
        old for the replay buffer, and detections refused because the track table was full
        (duplicates are not rejections: the network may deliver a message twice)."""
        out = dict(self._rejects.counts)
        for reason, n in (
            ("nav.too_old", self.nav.rejected_old),
            ("obstacles.too_old", self.scans.rejected_old),
            ("obstacles.track_limit", self.scans.state.refused),
        ):
            if n:
                out[reason] = n
        return out

    @property
    def resets(self) -> dict[str, int]:
        """Filters restarted: the vehicle filter (a long silence or divergence) and tracks."""
        return {"vehicle_filter": self.nav.state.resets, "tracks": self.scans.state.resets}

    @property
    def counters(self) -> dict[str, int]:
        """Fusion counters: accepted, rejected as too old, duplicates, replays, gated out."""
        return {
            "nav_fused": self.nav.fused,
            "nav_rejected_old": self.nav.rejected_old,
            "nav_duplicates": self.nav.duplicates,
            "nav_replays": self.nav.replays,
            "scans_fused": self.scans.fused,
            "scans_rejected_old": self.scans.rejected_old,
            "scans_duplicates": self.scans.duplicates,
            "scans_replays": self.scans.replays,
            "detections_gated_out": self.scans.state.gated_out,
            "fixes_gated_out": self.nav.state.fixes_gated,
        }
