"""The navigation measurements as a filter fuses them: z, R, the model h(s) and its Jacobian.

Three kinds reach the vehicle filter (services/estimator/unicycle.py's 7-state s):
- NavFix, the 10 Hz fix: z = [x, y, heading, speed through the water];
- Odometry, the AHRS, the propeller's speed and the DVL's bottom track: z = [heading + bias,
  yaw rate, v] and, with bottom lock, the velocity over ground in the body frame:
      u_g = v + cx cos(theta) + cy sin(theta),   v_g = vs - cx sin(theta) + cy cos(theta)
  (the hull's sway and the current's component across it are what the DVL sees sideways);
- PositionFix, a USBL/LBL fix every few seconds: z = [x, y], gated by its innovation.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from common.messages import NavFix, Odometry, PositionFix
from common.scalar import wrap_angle
from services.estimator.unicycle import BIAS, DIM_X, SWAY

FloatArray = NDArray[np.float64]

NavMeasurement = NavFix | Odometry | PositionFix
# the order of kinds at one stamp (the replay buffer's key: stamp, then seq * KINDS + kind)
KINDS: dict[type, int] = {NavFix: 0, Odometry: 1, PositionFix: 2}

_H_FIX = np.eye(4, DIM_X)  # x, y, theta, v observed directly
_H_POSITION = np.eye(2, DIM_X)


@dataclass(frozen=True, slots=True)
class Observation:
    """z: (m,) with noise R: (m, m), its model hx(s) -> (m,) and Jacobian H(s) -> (m, DIM_X);
    `angle` the index of a heading in z (its residual is wrapped, its mean circular)."""

    z: FloatArray
    R: FloatArray
    hx: Callable[[FloatArray], FloatArray]
    H: Callable[[FloatArray], FloatArray]
    angle: int | None

    def residual(self, a: FloatArray, b: FloatArray) -> FloatArray:
        """z - z' with the heading difference (if any) wrapped to [-pi, pi)."""
        y = np.subtract(a, b)
        if self.angle is not None:
            y[self.angle] = wrap_angle(float(y[self.angle]))
        return y

    def innovation(self, x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
        """(y, S): the innovation z - h(x) and its covariance H P H' + R, linearised at x."""
        H = self.H(x)
        return self.residual(self.z, self.hx(x)), H @ P @ H.T + self.R


@functools.lru_cache(maxsize=64)
def _diag(*stds: float) -> FloatArray:
    """The diagonal covariance of these standard deviations (variances at least 1e-12),
    read-only and kept: a sensor's noise figures repeat in every message of a mission."""
    s = np.asarray(stds, dtype=np.float64)
    R = np.diag(np.maximum(s * s, 1e-12))
    R.flags.writeable = False
    return R


def fix_noise(fix: NavFix) -> FloatArray:
    """R of a NavFix from its own noise figures: (4, 4)."""
    return _diag(fix.std_xy, fix.std_xy, fix.std_heading, fix.std_speed)


def of_fix(fix: NavFix, z: FloatArray) -> Observation:
    """A NavFix (z: its [x, y, heading, speed], pre-filtered or not; the raw R is kept: a
    pre-filtered fix's errors are correlated over the window, a reduced R over-confident)."""
    return Observation(
        z=z, R=fix_noise(fix), hx=lambda s: s[:4].copy(), H=lambda s: _H_FIX, angle=2
    )


def _odometry_h(s: FloatArray) -> FloatArray:
    _, _, th, v, w, cx, cy, b, vs = s.tolist()  # Python floats: cheaper, the same operations
    c, sn = math.cos(th), math.sin(th)
    return np.array([wrap_angle(th + b), w, v, v + cx * c + cy * sn, vs - cx * sn + cy * c])


def _odometry_jacobian(s: FloatArray) -> FloatArray:
    _, _, th, _, _, cx, cy, _, _ = s.tolist()
    c, sn = math.cos(th), math.sin(th)
    H = np.zeros((5, DIM_X))
    H[0, 2] = H[0, BIAS] = 1.0
    H[1, 4] = 1.0
    H[2, 3] = 1.0
    H[3, 2], H[3, 3], H[3, 5], H[3, 6] = -cx * sn + cy * c, 1.0, c, sn
    H[4, 2], H[4, 5], H[4, 6], H[4, SWAY] = -cx * c - cy * sn, -sn, c, 1.0
    return H


def of_odometry(m: Odometry) -> Observation:
    """AHRS heading and yaw rate, the rpm's speed through the water, and with bottom lock
    the DVL's velocity over ground."""
    if m.bottom_lock:
        return Observation(
            z=np.array([m.heading, m.yaw_rate, m.water_speed, m.u_ground, m.v_ground]),
            R=_diag(
                m.std_heading, m.std_yaw_rate, m.std_water_speed, m.std_velocity, m.std_velocity
            ),
            hx=_odometry_h,
            H=_odometry_jacobian,
            angle=0,
        )
    return Observation(
        z=np.array([m.heading, m.yaw_rate, m.water_speed]),
        R=_diag(m.std_heading, m.std_yaw_rate, m.std_water_speed),
        hx=lambda s: _odometry_h(s)[:3],
        H=lambda s: _odometry_jacobian(s)[:3],
        angle=0,
    )


def of_position(m: PositionFix) -> Observation:
    """A USBL/LBL position fix."""
    return Observation(
        z=np.array([m.x, m.y]),
        R=_diag(m.std_xy, m.std_xy),
        hx=lambda s: s[:2].copy(),
        H=lambda s: _H_POSITION,
        angle=None,
    )
