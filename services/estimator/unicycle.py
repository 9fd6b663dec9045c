"""The estimator's motion model: the unicycle of eqs. (1), (7) carried by an ocean current.

State s = [x, y, theta, v, w, cx, cy] (DIM_X = 7): the pose, the surge speed through the water
v and yaw rate w, and the current (cx, cy) that carries the vehicle over ground, world frame.
The current is a random walk: its only evidence is the difference between where the vehicle
goes over ground (position fixes, a DVL's bottom track) and where its heading and speed through
the water would take it. Without it, a cross current drove the filter off the vehicle: the
position could move only along the heading, so the sideways drift went into a belief that grew
overconfident across the track and no longer listened to the fixes (issue 60).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from common.scalar import wrap_angle

FloatArray = NDArray[np.float64]

DIM_X = 7
POSE = slice(0, 5)  # [x, y, theta, v, w]: what a StateEstimate carries with its covariance
CURRENT = slice(5, 7)


def fx(s: FloatArray, dt: float) -> FloatArray:
    """eqs. (1), (7) over ground: x' = v cos(theta) + cx, y' = v sin(theta) + cy, theta' = w;
    v, w and the current held. Midpoint-heading integration over dt (second order in dt)."""
    x, y, th, v, w, cx, cy = s
    mid = th + 0.5 * w * dt
    return np.array(
        [
            x + (v * math.cos(mid) + cx) * dt,
            y + (v * math.sin(mid) + cy) * dt,
            wrap_angle(th + w * dt),
            v,
            w,
            cx,
            cy,
        ]
    )


def jacobian_f(s: FloatArray, dt: float) -> FloatArray:
    """d fx / d s at s: (7, 7)."""
    _, _, th, v, w, _, _ = s
    mid = th + 0.5 * w * dt
    c, sn = math.cos(mid), math.sin(mid)
    F = np.eye(DIM_X)
    F[0, 2], F[0, 3], F[0, 4], F[0, 5] = -v * dt * sn, dt * c, -0.5 * v * dt * dt * sn, dt
    F[1, 2], F[1, 3], F[1, 4], F[1, 6] = v * dt * c, dt * sn, 0.5 * v * dt * dt * c, dt
    F[2, 4] = dt
    return F


def process_noise(
    s: FloatArray,
    dt: float,
    q_accel: float,
    q_yaw_accel: float,
    q_current: float,
    q_position: float,
) -> FloatArray:
    """Q: (7, 7) over dt for white surge acceleration (psd q_accel), yaw acceleration
    (q_yaw_accel), a random-walk current (psd q_current, integrated into the position) and a
    white velocity over ground in any direction (q_position: what the model leaves out, a
    hull's sideslip in a turn).

    The continuous white-noise model makes Q additive in dt, so splitting a prediction into
    sub-steps does not change the injected noise. Heading-to-position coupling within one
    step is O(v q dt^4) and left to the Jacobian of the next steps.
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
    for i, j in ((0, 5), (1, 6)):  # the current, a random walk the position integrates
        Q[i, i] += q_current * d3 + q_position * dt
        Q[i, j] = Q[j, i] = q_current * d2
        Q[j, j] = q_current * dt
    return Q


def residual_x(a: FloatArray, b: FloatArray) -> FloatArray:
    """s - s' with the heading difference wrapped to [-pi, pi)."""
    y = np.subtract(a, b)
    y[2] = wrap_angle(float(y[2]))
    return y


def circular_mean(
    sigmas: FloatArray, weights: FloatArray, angle_index: int | None = 2
) -> FloatArray:
    """Weighted mean of sigma points with the angle (if any) averaged on the circle (UKF)."""
    m = np.dot(weights, sigmas)
    if angle_index is not None:
        a = sigmas[:, angle_index]
        m[angle_index] = math.atan2(
            float(np.dot(weights, np.sin(a))), float(np.dot(weights, np.cos(a)))
        )
    return m
