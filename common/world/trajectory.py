"""Moving-obstacle trajectories alpha_k(t) with analytic velocity and acceleration (paper §2)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from common.config.world import MovingObstacleConfig

FloatArray = NDArray[np.float64]
# one time's (x, y, vx, vy, ax, ay): m, m/s, m/s^2
Motion = tuple[float, float, float, float, float, float]


class Trajectory(Protocol):
    """alpha_k(t): centre position, velocity and acceleration, vectorised over t; and at one
    time as plain floats, the very values `state` gives there (the plant asks at every step,
    and numpy's per-call cost is many times the arithmetic on one time)."""

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position, velocity, acceleration, each of shape t.shape + (2,)."""
        ...

    def position_at(self, t: float) -> tuple[float, float]:
        """Position (m) at one time t (s): state(t)'s, bit for bit."""
        ...

    def motion_at(self, t: float) -> Motion:
        """Position, velocity and acceleration at one time t (s): state(t)'s, bit for bit."""
        ...


class LineTrajectory:
    """alpha(t) = p0 + v t: constant velocity."""

    def __init__(self, p0: tuple[float, float], v: tuple[float, float]) -> None:
        self._p0 = np.array(p0, dtype=np.float64)
        self._v = np.array(v, dtype=np.float64)
        self._p0xy, self._vxy = _floats(self._p0), _floats(self._v)

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)[..., None]
        pos = self._p0 + self._v * tt
        vel = np.broadcast_to(self._v, pos.shape).copy()
        return pos, vel, np.zeros_like(pos)

    def position_at(self, t: float) -> tuple[float, float]:
        """Position (m) at one time t (s): p0 + v t, the same two IEEE operations per axis."""
        (x0, y0), (vx, vy) = self._p0xy, self._vxy
        return x0 + vx * t, y0 + vy * t

    def motion_at(self, t: float) -> Motion:
        """Position, velocity and acceleration at one time t (s) (velocity constant)."""
        x, y = self.position_at(t)
        vx, vy = self._vxy
        return x, y, vx, vy, 0.0, 0.0


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
        self._p0xy, self._vxy, self._nxy = _floats(self._p0), _floats(self._v), _floats(self._n)

    def state(self, t: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        tt = np.asarray(t, dtype=np.float64)[..., None]
        arg = self._omega * tt + self._phase
        a, w = self._amp, self._omega
        pos = self._p0 + self._v * tt + a * np.sin(arg) * self._n
        vel = self._v + a * w * np.cos(arg) * self._n
        acc = -a * w * w * np.sin(arg) * self._n
        return pos, vel, acc

    def position_at(self, t: float) -> tuple[float, float]:
        """Position (m) at one time t (s): state's operations in state's order, on floats."""
        # numpy's sin and cos, not math's: the ufuncs' last bit is not promised to be libm's
        return self._position(t, float(np.sin(self._omega * t + self._phase)))

    def motion_at(self, t: float) -> Motion:
        """Position, velocity and acceleration at one time t (s), as `state` computes them."""
        (vx, vy), (nx, ny) = self._vxy, self._nxy
        a, w = self._amp, self._omega
        arg = w * t + self._phase
        sin, cos = float(np.sin(arg)), float(np.cos(arg))
        a_w_cos, a_w_w_sin = a * w * cos, -a * w * w * sin
        x, y = self._position(t, sin)
        return x, y, vx + a_w_cos * nx, vy + a_w_cos * ny, a_w_w_sin * nx, a_w_w_sin * ny

    def _position(self, t: float, sin: float) -> tuple[float, float]:
        """p0 + v t + A sin n, given sin = sin(2 pi f t + phase)."""
        (x0, y0), (vx, vy), (nx, ny) = self._p0xy, self._vxy, self._nxy
        a_sin = self._amp * sin
        return x0 + vx * t + a_sin * nx, y0 + vy * t + a_sin * ny


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

    def position_at(self, t: float) -> tuple[float, float]:
        """Position (m) at one time t (s), through `state` (no scenario here loops waypoints)."""
        return self.motion_at(t)[:2]

    def motion_at(self, t: float) -> Motion:
        """Position, velocity and acceleration at one time t (s), through `state`."""
        pos, vel, acc = self.state(t)
        (x, y), (vx, vy), (ax, ay) = _floats(pos), _floats(vel), _floats(acc)
        return x, y, vx, vy, ax, ay


def _floats(v: FloatArray) -> tuple[float, float]:
    """A (2,) array's components as Python floats (the same values)."""
    return float(v[0]), float(v[1])


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
