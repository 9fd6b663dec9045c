"""The paper's smoothing stages on navigation fixes: mean filter eq. (2) and lag eq. (3)."""

from __future__ import annotations

import math
from collections import deque

import numpy as np
from numpy.typing import ArrayLike, NDArray

from common.config.estimator import PrefilterKind

FloatArray = NDArray[np.float64]


def mean_filter(x: ArrayLike, m: int) -> FloatArray:
    """eq. (2): y(n) = (1/m) sum_{i=1..m} x(n-i), over samples along axis 0.

    We read x(n-i), i = 1..m, as the m most recent samples received when output n is
    formed, i.e. a causal moving average that includes the newest sample; while fewer
    than m samples exist, the mean is over those available.
    """
    xs = np.asarray(x, dtype=np.float64)
    out = np.empty_like(xs)
    for n in range(len(xs)):
        out[n] = np.mean(xs[max(0, n - m + 1) : n + 1], axis=0)
    return out


def lag_step(u_prev: ArrayLike, e: ArrayLike, dt: float, T: float) -> FloatArray:
    """eq. (3): u_i = (dt e_i + T u_{i-1}) / (dt + T), the "virtual damping" first-order lag."""
    return (dt * np.asarray(e, dtype=np.float64) + T * np.asarray(u_prev, dtype=np.float64)) / (
        dt + T
    )


def lag_filter(e: ArrayLike, dt: ArrayLike, T: float) -> FloatArray:
    """eq. (3) over a sequence along axis 0; u_0 = e_0; dt[i] is the period before sample i."""
    es = np.asarray(e, dtype=np.float64)
    dts = np.broadcast_to(np.asarray(dt, dtype=np.float64), (len(es),))
    out = np.empty_like(es)
    for i in range(len(es)):
        out[i] = es[i] if i == 0 else lag_step(out[i - 1], es[i], float(dts[i]), T)
    return out


class MeanFilter:
    """Stateful eq. (2): a window of the last m samples."""

    def __init__(self, m: int) -> None:
        self.m = m
        self._window: deque[FloatArray] = deque(maxlen=m)

    def update(self, x: ArrayLike) -> FloatArray:
        """eq. (2): the mean of the last m samples, this one x: (d,) among them; (d,)."""
        self._window.append(np.asarray(x, dtype=np.float64))
        return np.asarray(np.mean(np.stack(tuple(self._window)), axis=0), dtype=np.float64)

    def copy(self) -> MeanFilter:
        """An independent filter in this state (a belief keeps its own, estimator/core.py)."""
        other = MeanFilter(self.m)
        other._window.extend(self._window)  # the stored arrays are never mutated
        return other


class LagFilter:
    """Stateful eq. (3) with inertia constant T; the first sample passes through."""

    def __init__(self, T: float) -> None:
        self.T = T
        self._u: FloatArray | None = None

    def update(self, e: ArrayLike, dt: float) -> FloatArray:
        """eq. (3): u: (d,) after sample e: (d,), dt seconds after the last one."""
        if self._u is None:
            self._u = np.array(e, dtype=np.float64)
        else:
            self._u = lag_step(self._u, e, dt, self.T)
        return self._u.copy()

    def copy(self) -> LagFilter:
        """An independent filter in this state."""
        other = LagFilter(self.T)
        other._u = None if self._u is None else self._u.copy()
        return other


class NavPrefilter:
    """The selected stage(s) applied to fixes z = (x, y, heading, speed), in stamp order.

    Heading is smoothed through its unit vector (cos, sin) and read back with atan2, so the
    stages average angles correctly across +-pi.
    """

    def __init__(self, kind: PrefilterKind, m: int, T: float) -> None:
        self.kind = kind
        self._mean = MeanFilter(m) if kind in ("mean", "mean+lag") else None
        self._lag = LagFilter(T) if kind in ("lag", "mean+lag") else None
        self._last_stamp: float | None = None

    def apply(self, stamp: float, z: FloatArray) -> FloatArray:
        """The stages' output for the fix z: (4,) = (x m, y m, heading rad, speed m/s) stamped
        `stamp` (s), later than the last; (4,), its heading from atan2 (within [-pi, pi])."""
        if self._mean is None and self._lag is None:
            return z
        v = np.array([z[0], z[1], math.cos(z[2]), math.sin(z[2]), z[3]])
        if self._mean is not None:
            v = self._mean.update(v)
        if self._lag is not None:
            dt = 0.0 if self._last_stamp is None else stamp - self._last_stamp
            v = self._lag.update(v, dt)
        self._last_stamp = stamp
        return np.array([v[0], v[1], math.atan2(v[3], v[2]), v[4]])

    def copy(self) -> NavPrefilter:
        """An independent prefilter in this state (a belief keeps its own, estimator/core.py)."""
        other = NavPrefilter.__new__(NavPrefilter)
        other.kind = self.kind
        other._mean = None if self._mean is None else self._mean.copy()
        other._lag = None if self._lag is None else self._lag.copy()
        other._last_stamp = self._last_stamp
        return other
