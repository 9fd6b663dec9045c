"""Moving-obstacle trajectories alpha_k(t) with analytic velocity and acceleration (paper §2)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from common.config.world import MovingObstacleConfig

FloatArray = NDArray[np.float64]


class Trajectory(Protocol):
    """alpha_k(t): centre position, velocity and acceleration, vectorised over t."""

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position, velocity, acceleration, each of shape t.shape + (2,)."""
        ...


class LineTrajectory:
    """alpha(t) = p0 + v t: constant velocity."""

    def __init__(self, p0: tuple[float, float], v: tuple[float, float]) -> None:
        self._p0 = np.array(p0, dtype=np.float64)
        self._v = np.array(v, dtype=np.float64)

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)[..., None]
        pos = self._p0 + self._v * tt
        vel = np.broadcast_to(self._v, pos.shape).copy()
        return pos, vel, np.zeros_like(pos)


class SinusoidTrajectory:
    """alpha(t) = p0 + v t + A sin(2 pi f t + phase) n, with n the unit left normal of v."""

    def __init__(
        self, p0: tuple[float, float], v: tuple[float, float], amp: float, freq: float, phase: float
    ) -> None:
        self._p0 = np.array(p0, dtype=np.float64)
        self._v = np.array(v, dtype=np.float64)
        speed = math.hypot(*v)
        self._n = np.array((-v[1] / speed, v[0] / speed))
        self._amp, self._omega, self._phase = amp, 2.0 * math.pi * freq, phase

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)[..., None]
        arg = self._omega * tt + self._phase
        a, w = self._amp, self._omega
        pos = self._p0 + self._v * tt + a * np.sin(arg) * self._n
        vel = self._v + a * w * np.cos(arg) * self._n
        acc = -a * w * w * np.sin(arg) * self._n
        return pos, vel, acc


class WaypointLoop:
    """Closed polyline p0 -> w1 -> ... -> wn -> p0 travelled at constant speed, looping.

    Acceleration is reported as zero: the turns at the vertices are instantaneous.
    """

    def __init__(self, points: FloatArray, speed: float) -> None:
        self._a = points
        b = np.roll(points, -1, axis=0)
        seg = b - points
        self._len = np.hypot(seg[:, 0], seg[:, 1])
        self._dir = seg / np.where(self._len > 0.0, self._len, 1.0)[:, None]
        self._cum = np.concatenate(([0.0], np.cumsum(self._len)))
        self._loop = float(self._cum[-1])
        self._speed = speed

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)
        s = np.mod(self._speed * tt, self._loop)  # arc length along the loop
        i = np.clip(np.searchsorted(self._cum, s, side="right") - 1, 0, len(self._len) - 1)
        pos = self._a[i] + (s - self._cum[i])[..., None] * self._dir[i]
        vel = self._speed * self._dir[i]
        return pos, vel, np.zeros_like(pos)


def make_trajectory(cfg: MovingObstacleConfig) -> Trajectory:
    """The trajectory of one moving obstacle, chosen once by its kind."""
    p0 = (cfg.x0_m, cfg.y0_m)
    v = (cfg.vx_mps, cfg.vy_mps)
    if cfg.kind == "line":
        return LineTrajectory(p0, v)
    if cfg.kind == "sinusoid":
        return SinusoidTrajectory(p0, v, cfg.amplitude_m, cfg.frequency_hz, cfg.phase_rad)
    pts = np.vstack(([p0], np.asarray(cfg.waypoints_m, dtype=np.float64).reshape(-1, 2)))
    return WaypointLoop(pts, cfg.speed_mps)
