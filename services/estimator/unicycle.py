"""The estimator's motion model: the unicycle of eqs. (1), (7) carried by an ocean current.

State s = [x, y, theta, v, w, cx, cy, b, vs] (DIM_X = 9): the pose, the surge speed through
the water v and yaw rate w, the current (cx, cy) that carries the vehicle over ground, world
frame, the AHRS's heading bias b (an AUV's heading sensor reads theta + b; a constant bias
that the filter took for noise made it average the readings into a heading it was sure of,
and wrong: dead reckoning then drifted across the track faster than its covariance said),
and the hull's sway through the water vs (a real hull slips sideways in a turn, which a DVL
sees; without it the filter took the slip for a current that outlived the turn).

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

DIM_X = 9
POSE = slice(0, 5)  # [x, y, theta, v, w]: what a StateEstimate carries with its covariance
CURRENT = slice(5, 7)
BIAS = 7  # the AHRS heading bias (rad)
SWAY = 8  # the hull's sway through the water (m/s, to port)
# the bias's random walk (rad^2/s): essentially constant over a mission, and P stays regular
Q_BIAS = 1e-9


def fx(s: FloatArray, dt: float, sway_tau_s: float = 2.0) -> FloatArray:
    """eqs. (1), (7) over ground, with the hull's sway and the current:
    x' = v cos(theta) - vs sin(theta) + cx, y' = v sin(theta) + vs cos(theta) + cy, theta' = w;
    v, w, the current and the bias held; the sway decays with sway_tau_s (Gauss-Markov).
    Midpoint-heading integration over dt (second order in dt)."""
    # Python floats: the same IEEE operations as on numpy's scalars, at a fraction of the cost
    x, y, th, v, w, cx, cy, b, vs = s.tolist()
    mid = th + 0.5 * w * dt
    c, sn = math.cos(mid), math.sin(mid)
    return np.array(
        [
            x + (v * c - vs * sn + cx) * dt,
            y + (v * sn + vs * c + cy) * dt,
            wrap_angle(th + w * dt),
            v,
            w,
            cx,
            cy,
            b,
            vs * math.exp(-dt / sway_tau_s),
        ]
    )


def jacobian_fixed(dt: float, sway_tau_s: float = 2.0) -> FloatArray:
    """The entries of d fx / d s (9, 9) that depend on dt alone (the state's, `jacobian_at`,
    zero): a filter keeps them for each sub-step length."""
    F = np.eye(DIM_X)
    F[0, 5] = F[1, 6] = F[2, 4] = dt
    F[SWAY, SWAY] = math.exp(-dt / sway_tau_s)
    return F


def jacobian_at(F: FloatArray, s: FloatArray, dt: float) -> FloatArray:
    """d fx / d s at s: its entries that depend on the state written into F (9, 9), which
    holds jacobian_fixed(dt) (a copy: it is modified and returned)."""
    _, _, th, v, w, _, _, _, vs = s.tolist()  # Python floats, as in fx
    mid = th + 0.5 * w * dt
    c, sn = math.cos(mid), math.sin(mid)
    dx_dth, dy_dth = (-v * sn - vs * c) * dt, (v * c - vs * sn) * dt
    F[0, 2], F[0, 3], F[0, 4] = dx_dth, dt * c, 0.5 * dt * dx_dth
    F[1, 2], F[1, 3], F[1, 4] = dy_dth, dt * sn, 0.5 * dt * dy_dth
    F[0, SWAY], F[1, SWAY] = -dt * sn, dt * c
    return F


def process_noise_fixed(
    dt: float,
    q_accel: float,
    q_yaw_accel: float,
    q_current: float,
    q_position: float,
    sway_std_mps: float = 0.0,
    sway_tau_s: float = 2.0,
) -> FloatArray:
    """Q: (9, 9) over dt for white surge acceleration (psd q_accel), yaw acceleration
    (q_yaw_accel), a random-walk current (psd q_current, integrated into the position), a
    white velocity over ground in any direction (q_position: what the model still leaves
    out), the Gauss-Markov sway (stationary std sway_std_mps) and the bias's slow walk.

    The continuous white-noise model makes Q additive in dt, so splitting a prediction into
    sub-steps does not change the injected noise (the sway's exact discretisation is, over
    sub-steps, to first order). Heading-to-position coupling within one step is
    O(v q dt^4) and left to the Jacobian of the next steps.

    These are its entries that do not depend on the state (the surge noise along the heading,
    `process_noise_at`, zero; the position's own walk on its diagonal): a filter keeps them
    for each sub-step length.
    """
    d2, d3 = dt * dt / 2.0, dt**3 / 3.0
    Q = np.zeros((DIM_X, DIM_X))
    Q[3, 3] = q_accel * dt
    Q[2, 2], Q[2, 4], Q[4, 2], Q[4, 4] = (
        q_yaw_accel * d3,
        q_yaw_accel * d2,
        q_yaw_accel * d2,
        (q_yaw_accel * dt),
    )
    for i, j in ((0, 5), (1, 6)):  # the current, a random walk the position integrates
        Q[i, i] = q_current * d3 + q_position * dt
        Q[i, j] = Q[j, i] = q_current * d2
        Q[j, j] = q_current * dt
    Q[BIAS, BIAS] = Q_BIAS * dt
    Q[SWAY, SWAY] = sway_std_mps**2 * (1.0 - math.exp(-2.0 * dt / sway_tau_s))
    return Q


def process_noise_at(Q: FloatArray, s: FloatArray, dt: float, q_accel: float) -> FloatArray:
    """Q at s: the white surge acceleration along the heading at mid-step, h =
    (cos, sin), added into Q (9, 9), which holds process_noise_fixed(dt, ...) (a copy: it is
    modified and returned): q_accel dt^3/3 h h' on the position, q_accel dt^2/2 h with v."""
    _, _, th, _, w, _, _, _, _ = s.tolist()  # Python floats, as in fx
    c, sn = math.cos(th + 0.5 * w * dt), math.sin(th + 0.5 * w * dt)
    a3, a2 = q_accel * (dt**3 / 3.0), q_accel * (dt * dt / 2.0)
    Q[0, 0] = a3 * (c * c) + Q[0, 0]  # plus the walk of process_noise_fixed
    Q[1, 1] = a3 * (sn * sn) + Q[1, 1]
    Q[0, 1], Q[1, 0] = a3 * (c * sn), a3 * (sn * c)
    Q[0, 3] = Q[3, 0] = a2 * c
    Q[1, 3] = Q[3, 1] = a2 * sn
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
