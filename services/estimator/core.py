"""The estimator core: fuses delayed nav fixes and obstacle scans; publishes state and tracks."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from common.config.estimator import EstimatorConfig
from common.messages import NavFix, ObstacleDetections, ObstacleTracks, StateEstimate
from common.runtime.model.core import Delivery, Emit
from common.scalar import wrap_angle
from services.estimator.prefilter import NavPrefilter
from services.estimator.replay import ReplayBuffer
from services.estimator.tracks import ObstacleTracker, TrackerState
from services.estimator.vehicle_filter import make_vehicle_filter

FloatArray = NDArray[np.float64]


@dataclass(frozen=True, kw_only=True, slots=True)
class VehicleBelief:
    """The vehicle Gaussian (x, P) at `stamp` (None before the first fix) + pre-filter memory."""

    x: FloatArray  # [x, y, theta, v, w]
    P: FloatArray
    stamp: float | None
    prefilter: NavPrefilter  # never mutated once stored: fusing works on a copy


class EstimatorCore:
    """Vehicle EKF/UKF over (prefiltered) fixes and per-id obstacle tracks, all fused at their
    sampling stamps with roll-back for late arrivals; outputs are predicted to the step time.
    """

    def __init__(self, cfg: EstimatorConfig, start: tuple[float, float, float]) -> None:
        self.cfg = cfg
        self._filter = make_vehicle_filter(cfg)
        self._tracker = ObstacleTracker(cfg)
        x0 = np.array([start[0], start[1], wrap_angle(start[2]), 0.0, 0.0])
        std0 = (cfg.init_std_xy_m, cfg.init_std_xy_m, cfg.init_std_theta_rad)
        P0 = np.diag(np.square(std0 + (cfg.init_std_v_mps, cfg.init_std_w_rps)))
        prefilter = NavPrefilter(cfg.prefilter, cfg.mean_window, cfg.lag_time_constant_s)
        belief = VehicleBelief(x=x0, P=P0, stamp=None, prefilter=prefilter)
        self.nav: ReplayBuffer[NavFix, VehicleBelief] = ReplayBuffer(
            belief, self._fuse_fix, cfg.history_s
        )
        self.scans: ReplayBuffer[ObstacleDetections, TrackerState] = ReplayBuffer(
            TrackerState(tracks={}), self._tracker.fuse, cfg.history_s
        )

    def _fuse_fix(self, b: VehicleBelief, fix: NavFix) -> VehicleBelief:
        prefilter = b.prefilter.copy()
        z = prefilter.apply(fix.stamp, np.array([fix.x, fix.y, fix.heading, fix.speed]))
        dt = 0.0 if b.stamp is None else fix.stamp - b.stamp
        x, P = self._filter.predict(b.x, b.P, dt)
        # R from the fix's own noise figures; a pre-filtered fix keeps the raw R (its errors
        # are correlated over the window, so a reduced R would be over-confident)
        stds = np.array([fix.std_xy, fix.std_xy, fix.std_heading, fix.std_speed])
        R = np.diag(np.maximum(stds * stds, 1e-12))
        x, P = self._filter.update(x, P, z, R)
        return VehicleBelief(x=x, P=P, stamp=fix.stamp, prefilter=prefilter)

    def deliver(self, d: Delivery) -> list[Emit]:
        msg = d.msg
        if isinstance(msg, NavFix):
            self.nav.add(msg, msg.stamp, msg.seq)
        elif isinstance(msg, ObstacleDetections):
            self.scans.add(msg, msg.stamp, msg.seq)
        return []

    def belief_at(self, t: float) -> tuple[FloatArray, FloatArray]:
        """The vehicle belief (x, P) predicted from the last fused fix to time t."""
        b = self.nav.state
        if b.stamp is None:
            return b.x.copy(), b.P.copy()
        return self._filter.predict(b.x, b.P, t - b.stamp)

    def step(self, t: float) -> list[Emit]:
        x, P = self.belief_at(t)
        state = StateEstimate(
            stamp=t,
            x=float(x[0]),
            y=float(x[1]),
            theta=float(x[2]),
            v=float(x[3]),
            w=float(x[4]),
            covariance=tuple(P.ravel().tolist()),  # Python floats, row-major
        )
        tracks = ObstacleTracks(stamp=t, tracks=self._tracker.tracks_at(self.scans.state, t))
        return [Emit(stream="state", msg=state), Emit(stream="tracks", msg=tracks)]

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
        }
