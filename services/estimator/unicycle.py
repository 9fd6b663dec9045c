"""The unicycle motion model (eqs. 1, 7) and the NavFix measurement model, as pure functions.

State s = [x, y, theta, v, w]; fix z = [x, y, heading, speed].
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from common.scalar import wrap_angle

FloatArray = NDArray[np.float64]

DIM_X = 5
DIM_Z = 4
H_NAV = np.eye(DIM_Z, DIM_X)  # the fix observes x, y, theta, v directly


def fx(s: FloatArray, dt: float) -> FloatArray:
    """eqs. (1), (7): x' = v cos(theta), y' = v sin(theta), theta' = w; v, w held.

    Midpoint-heading integration over dt (second order in dt).
    """
    x, y, th, v, w = s
    mid = th + 0.5 * w * dt
    return np.array(
        [x + v * dt * math.cos(mid), y + v * dt * math.sin(mid), wrap_angle(th + w * dt), v, w]
    )


def jacobian_f(s: FloatArray, dt: float) -> FloatArray:
    """d fx / d s at s."""
    _, _, th, v, w = s
    mid = th + 0.5 * w * dt
    c, sn = math.cos(mid), math.sin(mid)
    F = np.eye(DIM_X)
    F[0, 2], F[0, 3], F[0, 4] = -v * dt * sn, dt * c, -0.5 * v * dt * dt * sn
    F[1, 2], F[1, 3], F[1, 4] = v * dt * c, dt * sn, 0.5 * v * dt * dt * c
    F[2, 4] = dt
    return F


def process_noise(s: FloatArray, dt: float, q_accel: float, q_yaw_accel: float) -> FloatArray:
    """Q over dt for white surge acceleration (psd q_accel) and yaw acceleration (q_yaw_accel).

    The continuous white-noise model (integrated random walks) makes Q additive in dt, so
    splitting a prediction into sub-steps does not change the injected noise. Surge noise
    moves the position along the heading; heading-to-position coupling within one step is
    O(v q dt^4) and left to the Jacobian of the next steps.
    """
    th, w = s[2], s[4]
    h = np.array([math.cos(th + 0.5 * w * dt), math.sin(th + 0.5 * w * dt)])
    d2, d3 = dt * dt / 2.0, dt**3 / 3.0
    Q = np.zeros((DIM_X, DIM_X))
    Q[0:2, 0:2] = q_accel * d3 * np.outer(h, h)
    Q[0:2, 3] = Q[3, 0:2] = q_accel * d2 * h
    Q[3, 3] = q_accel * dt
    Q[2, 2], Q[2, 4], Q[4, 2], Q[4, 4] = (
        q_yaw_accel * d3,
        q_yaw_accel * d2,
        q_yaw_accel * d2,
        (q_yaw_accel * dt),
    )
    return Q


def hx(s: FloatArray) -> FloatArray:
    """The fix a state would produce: [x, y, theta, v]."""
    return np.array([s[0], s[1], s[2], s[3]])


def jacobian_h(s: FloatArray) -> FloatArray:
    return H_NAV


def residual_z(a: FloatArray, b: FloatArray) -> FloatArray:
    """z - z' with the heading difference wrapped to [-pi, pi)."""
    y = np.subtract(a, b)
    y[2] = wrap_angle(float(y[2]))
    return y


def residual_x(a: FloatArray, b: FloatArray) -> FloatArray:
    """s - s' with the heading difference wrapped to [-pi, pi)."""
    y = np.subtract(a, b)
    y[2] = wrap_angle(float(y[2]))
    return y


def circular_mean(sigmas: FloatArray, weights: FloatArray, angle_index: int = 2) -> FloatArray:
    """Weighted mean of sigma points with the angle averaged on the circle (for the UKF)."""
    m = np.dot(weights, sigmas)
    a = sigmas[:, angle_index]
    m[angle_index] = math.atan2(
        float(np.dot(weights, np.sin(a))), float(np.dot(weights, np.cos(a)))
    )
    return m
