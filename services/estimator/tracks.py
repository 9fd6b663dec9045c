"""Obstacle tracks: one IMM (constant velocity + constant acceleration) per detected id."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from common.config.estimator import EstimatorConfig
from common.config.sensor import SensorConfig
from common.guard import MAX_ITEMS
from common.messages import Detection, ObstacleDetections, Track
from services.estimator.gate import ChiSquareGate
from services.estimator.health import healthy, healthy_entries
from services.estimator.imm import ImmFilter, Modes, combine, innovation

FloatArray = NDArray[np.float64]

# filter state [x, vx, ax, y, vy, ay]; published as Track fields and covariance in the
# order [x, y, vx, vy, ax, ay]: the covariance's entries, row-major, at these flat indices
_TO_MSG = np.array([0, 3, 1, 4, 2, 5])
_TO_MSG_FLAT = (_TO_MSG[:, None] * 6 + _TO_MSG).ravel()
# a coasting track is dropped once its predicted centre is this many standard deviations
# inside the sonar's sector and still not detected (ObstacleTracker._seen_there)
VIEW_SIGMAS = 2.0


@dataclass(frozen=True, kw_only=True, slots=True)
class TrackBelief:
    """One track at `stamp` (its last accepted detection): its IMM belief and the radius
    estimate. Arrays are never modified once stored.
    """

    id: int
    modes: Modes
    stamp: float
    radius: float
    radius_var: float


@dataclass(frozen=True, kw_only=True, slots=True)
class TrackerState:
    """All tracks after some scans, and on the way: detections the gate rejected, detections
    of new ids refused because MAX_ITEMS tracks were live, tracks restarted (diverged)."""

    tracks: Mapping[int, TrackBelief]  # never mutated: fuse builds a new mapping
    gated_out: int = 0
    refused: int = 0
    resets: int = 0


def _variance(std: float) -> float:
    """A detection's position variance (std^2, at least 1e-12: R stays invertible)."""
    return max(std**2, 1e-12)


class ObstacleTracker:
    """Associates detections to tracks by id, gates them (chi-square, per mode) and fuses.

    At most MAX_ITEMS tracks are held (a detection of one more id is refused: the work of
    every publish grows with the tracks); a track whose filter diverges restarts from its
    detection. With the sonar's sector (`sonar`), a track predicted outside it coasts up to
    track_coast_s (EstimatorConfig); without, every track is dropped after track_timeout_s.
    """

    def __init__(self, cfg: EstimatorConfig, sonar: SensorConfig | None = None) -> None:
        self.cfg = cfg
        self.sonar = sonar
        # how long a track is remembered: a coasting one until track_coast_s
        self._memory_s = max(cfg.track_timeout_s, cfg.track_coast_s if sonar else 0.0)
        self.gate = ChiSquareGate(cfg.track_gate_probability)
        self._imm = ImmFilter(
            cfg.track_cv_accel_psd_m2_s3,
            cfg.track_jerk_psd_m2_s5,
            cfg.track_cv_sojourn_s,
            cfg.track_ca_sojourn_s,
        )

    def _start(
        self, oid: int, stamp: float, z: FloatArray, var: float, r: float, r_var: float
    ) -> TrackBelief:
        x = np.array([z[0], 0.0, 0.0, z[1], 0.0, 0.0])
        axis = [var, self.cfg.track_init_std_v_mps**2, self.cfg.track_init_std_a_mps2**2]
        P = np.diag(axis * 2)
        return TrackBelief(
            id=oid,
            modes=Modes(np.stack((x, x)), np.stack((P, P)), np.array([0.5, 0.5])),
            stamp=stamp,
            radius=r,
            radius_var=r_var,
        )

    def _fused_together(
        self, tracks: Mapping[int, TrackBelief], detections: Sequence[Detection], stamp: float
    ) -> dict[int, tuple[TrackBelief, Modes | None]]:
        """The scan's detections of tracks it updates (one detection each, the track
        0 < age <= track_timeout_s), fused together, by id: (the track's belief, its
        posterior, None if gated out). Each step of `_fused` is then one numpy call per
        operation for all of them, the same floats as one by one; nothing for fewer than two.
        """
        timeout = self.cfg.track_timeout_s
        times = Counter(det.id for det in detections)
        ahead = [
            (det, b)
            for det in detections
            if times[det.id] == 1
            and (b := tracks.get(det.id)) is not None
            and 0.0 < stamp - b.stamp <= timeout
        ]
        if len(ahead) < 2:
            return {}
        m = self._imm.predict_many([b.modes for _, b in ahead], [stamp - b.stamp for _, b in ahead])
        z = np.array([[det.x, det.y] for det, _ in ahead])
        R = np.eye(2) * np.array([_variance(det.std_xy) for det, _ in ahead])[:, None, None]
        inside = np.flatnonzero(self._gates(m, z, R))
        out: dict[int, tuple[TrackBelief, Modes | None]] = {det.id: (b, None) for det, b in ahead}
        if len(inside):
            post = self._imm.update(Modes(*(a[inside] for a in m)), z[inside], R[inside])
            for k, i in enumerate(inside.tolist()):
                det, b = ahead[i]
                out[det.id] = (b, Modes(post.xs[k], post.Ps[k], post.mu[k]))
        return out

    def _fused(self, modes: Modes, dt: float, z: FloatArray, R: FloatArray) -> Modes | None:
        """One track's IMM belief predicted dt ahead and updated with detection z (2,) of
        noise R (2, 2); None if z is outside its gate."""
        prior = self._imm.predict(modes, dt)
        one = Modes(prior.xs[None], prior.Ps[None], prior.mu[None])
        if not self._gates(one, z[None], R[None])[0]:
            return None
        return self._imm.update(prior, z, R)

    def _gates(self, m: Modes, z: FloatArray, R: FloatArray) -> list[bool]:
        """Whether each detection z[k] (k, 2) of noise R[k] (k, 2, 2) falls in the gate of
        track k (m: stacked (k, ...)): of its combined belief, or of any one mode's. A
        manoeuvre starts where the steady mode, which dominates the mixture, is surest: a
        gate on the mixture alone would refuse the very detections that tell the manoeuvring
        mode it is right, and the track would coast on its old velocity.
        """
        return [any(d <= self.gate.threshold for d in one) for one in self._distances(m, z, R)]

    @staticmethod
    def _distances(m: Modes, z: FloatArray, R: FloatArray) -> list[list[float]]:
        """For each track k of the stack m, the squared Mahalanobis distances y' S^-1 y of
        detection z[k] (k, 2), noise R[k] (k, 2, 2), from its combined belief and each mode
        (ChiSquareGate.accepts' arithmetic, every belief of the stack at once)."""
        x, P = combine(*m)
        xs = np.concatenate((x[:, None], m.xs), axis=1)  # (k, 3, 6): the mixture, each mode
        Ps = np.concatenate((P[:, None], m.Ps), axis=1)
        ys, Ss = innovation(xs, Ps, z[:, None, :], R[:, None])
        sols = np.linalg.solve(Ss, ys[..., None])[..., 0]
        return [
            [float(y @ s) for y, s in zip(yk, sk, strict=True)]
            for yk, sk in zip(ys, sols, strict=True)
        ]

    def fuse(self, state: TrackerState, msg: ObstacleDetections) -> TrackerState:
        """The tracks after one scan (stamped msg.stamp, fused in id order)."""
        timeout = self.cfg.track_timeout_s
        # forget tracks that can never be published again (t >= msg.stamp from now on)
        out = {k: b for k, b in state.tracks.items() if msg.stamp - b.stamp <= self._memory_s}
        gated_out, refused, resets = state.gated_out, state.refused, state.resets
        detections = sorted(msg.detections, key=lambda d: d.id)
        together = self._fused_together(out, detections, msg.stamp)
        for det in detections:
            z = np.array([det.x, det.y])
            var = _variance(det.std_xy)
            r_var = max(det.std_radius**2, 1e-12)
            b = out.get(det.id)
            # a detection of a forgotten id, or of one coasting past track_timeout_s (its
            # prediction has drifted), starts a fresh track
            if b is None or msg.stamp - b.stamp > timeout:
                if len(out) >= MAX_ITEMS:
                    refused += 1
                    continue
                out[det.id] = self._start(det.id, msg.stamp, z, var, det.radius, r_var)
                continue
            fused = together.get(det.id)
            if fused is not None and fused[0] is b:
                post = fused[1]
            else:
                post = self._fused(b.modes, msg.stamp - b.stamp, z, np.eye(2) * var)
            if post is None:
                gated_out += 1
                continue
            if not all(healthy(x, P) for x, P in zip(post.xs, post.Ps, strict=True)):
                resets += 1
                out[det.id] = self._start(det.id, msg.stamp, z, var, det.radius, r_var)
                continue
            # the radius is constant: inverse-variance weighted mean of its measurements
            w = b.radius_var / (b.radius_var + r_var)
            out[det.id] = TrackBelief(
                id=det.id,
                modes=post,
                stamp=msg.stamp,
                radius=b.radius + w * (det.radius - b.radius),
                radius_var=b.radius_var * r_var / (b.radius_var + r_var),
            )
        return TrackerState(tracks=out, gated_out=gated_out, refused=refused, resets=resets)

    def _seen_there(
        self, x: FloatArray, P: FloatArray, radius: float, pose: tuple[float, float, float] | None
    ) -> bool:
        """Whether the sonar at `pose` (x, y, heading) would see an obstacle predicted as (x, P)
        (True without a sector or a pose: a track is then dropped at track_timeout_s)."""
        if self.sonar is None or pose is None:
            return True
        # a missed detection says the obstacle is gone only where the sonar would surely see
        # it: its predicted centre VIEW_SIGMAS standard deviations inside the sector's edges
        ox, oy = float(x[0]), float(x[3])
        if not self.sonar.sees(*pose, ox, oy, radius):
            return False  # not even its centre: no margin (>= 0) can make the sonar see it
        pos = P[::3, ::3]  # the covariance of (x, y): rows and columns 0 and 3
        sigma = math.sqrt(max(0.0, float(np.linalg.eigvalsh(pos)[-1])))
        return self.sonar.sees(*pose, ox, oy, radius, VIEW_SIGMAS * sigma)

    def predict(self, b: TrackBelief, t: float) -> tuple[FloatArray, FloatArray]:
        """The combined Gaussian of track b at time t, state order [x, vx, ax, y, vy, ay]."""
        return combine(*self._imm.predict(b.modes, t - b.stamp))

    def predict_all(
        self, beliefs: Sequence[TrackBelief], t: float
    ) -> tuple[FloatArray, FloatArray]:
        """`predict` of each track to t, stacked: x (k, 6), P (k, 6, 6); those before t
        together (ImmFilter.predict_many: the same floats, one numpy call per operation for
        all of them)."""
        ahead = [b for b in beliefs if t - b.stamp > 0.0]
        if len(ahead) >= 2:
            modes = self._imm.predict_many([b.modes for b in ahead], [t - b.stamp for b in ahead])
            if len(ahead) == len(beliefs):  # every one (nearly always): combine's own stack
                return combine(*modes)
            together = iter(zip(*combine(*modes), strict=True))
            each = [next(together) if t - b.stamp > 0.0 else self.predict(b, t) for b in beliefs]
        else:
            each = [self.predict(b, t) for b in beliefs]
        if not each:
            return np.empty((0, 6)), np.empty((0, 6, 6))
        # np.array of a list of equal arrays stacks them (copies: the same floats)
        return np.array([x for x, _ in each]), np.array([P for _, P in each])

    def tracks_at(
        self, state: TrackerState, t: float, pose: tuple[float, float, float] | None = None
    ) -> tuple[Track, ...]:
        """The tracks updated within track_timeout_s of t, and those coasting up to
        track_coast_s that the sonar, at the vehicle's pose (x, y, heading), would not see,
        predicted to t as wire tracks ([x, y, vx, vy, ax, ay] covariance); the others are
        dropped."""
        out: list[Track] = []
        kept = [
            (oid, b) for oid, b in sorted(state.tracks.items()) if t - b.stamp <= self._memory_s
        ]
        xs, Ps = self.predict_all([b for _, b in kept], t)
        # Python floats, each covariance row-major in the wire's order (as healthy as P): for
        # every track at once, a copy of the same floats (two numpy calls, not two a track)
        means = xs.tolist()
        covariances = Ps.reshape(len(kept), 36)[:, _TO_MSG_FLAT].tolist()
        for i, ((oid, b), mean, covariance) in enumerate(
            zip(kept, means, covariances, strict=True)
        ):
            if not healthy_entries(mean, covariance):
                continue  # never publish a non-finite track (its next detection restarts it)
            if t - b.stamp > self.cfg.track_timeout_s and self._seen_there(
                xs[i], Ps[i], b.radius, pose
            ):
                continue  # where the sonar would see it, and does not: gone
            px, pvx, pax, py, pvy, pay = mean
            out.append(
                Track(
                    id=oid,
                    x=px,
                    y=py,
                    vx=pvx,
                    vy=pvy,
                    ax=pax,
                    ay=pay,
                    radius=max(0.0, b.radius),
                    covariance=tuple(covariance),
                )
            )
        return tuple(out)
