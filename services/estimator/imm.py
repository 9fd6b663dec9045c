"""Interacting multiple models for one obstacle: constant velocity + constant acceleration.

Both modes share the state [x, vx, ax, y, vy, ay] (filterpy's order_by_dim); the CV mode
holds the acceleration at zero. Mixing and combination follow Bar-Shalom's IMM; the
per-mode update runs through filterpy's KalmanFilter, the per-mode predict through
`kf_predict`, the same equations as filterpy's KalmanFilter.predict without its object
overhead (the estimator predicts every track to every publish time: the hot path).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numpy.typing import NDArray

from services.estimator.filterpy_lazy import KalmanFilter

FloatArray = NDArray[np.float64]

H_POS = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 1.0, 0, 0]])  # a detection sees x, y


class Modes(NamedTuple):
    """An IMM belief: each mode's mean xs[j] (6,) and covariance Ps[j] (6, 6), modes (CV, CA),
    and the mode probabilities mu (2,)."""

    xs: tuple[FloatArray, ...]
    Ps: tuple[FloatArray, ...]
    mu: FloatArray


def innovation(
    x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A detection z (2,) against the Gaussian (x, P): y = z - H x (2,), S = H P H' + R (2, 2)."""
    return z - H_POS @ x, H_POS @ P @ H_POS.T + R


def transition(dt: float, constant_acceleration: bool) -> FloatArray:
    """F over dt: constant acceleration, or constant velocity with the acceleration zeroed."""
    F = np.zeros((6, 6))
    for b in (0, 3):  # one block per axis
        F[b, b] = F[b + 1, b + 1] = 1.0
        F[b, b + 1] = dt
        if constant_acceleration:
            F[b, b + 2], F[b + 1, b + 2], F[b + 2, b + 2] = 0.5 * dt * dt, dt, 1.0
    return F


def process_noise(dt: float, constant_acceleration: bool, psd: float) -> FloatArray:
    """Q over dt (6, 6) as filterpy's Q_discrete_white_noise makes it, its var scaled so that
    the injected noise matches white jerk (CA) or white acceleration (CV) of intensity psd:
    Q_aa = psd dt (CA) and Q_vv = psd dt (CV), whatever the step.

    filterpy's blocks, built here directly: its block_diag (scipy's) cost ~50 us a call, and
    a track predicted to a new dt builds two (tests/test_estimator_tracks.py holds the two
    equal bit for bit).
    """
    Q = np.zeros((6, 6))
    if constant_acceleration:
        q3 = np.array(_white_noise_blocks(3, dt))
        Q[0:3, 0:3] = q3
        Q[3:6, 3:6] = q3
        return Q * (psd * dt)  # block_diag(q3, q3) * var
    q2 = np.array(_white_noise_blocks(2, dt)) * (psd / dt)
    for base in (0, 3):
        Q[base : base + 2, base : base + 2] = q2
    return Q


def _white_noise_blocks(dim: int, dt: float) -> list[list[float]]:
    """One axis's block of Q_discrete_white_noise(dim, dt) before its var: filterpy's own
    expressions, so the same floats."""
    if dim == 2:
        return [[0.25 * dt**4, 0.5 * dt**3], [0.5 * dt**3, dt**2]]
    return [
        [0.25 * dt**4, 0.5 * dt**3, 0.5 * dt**2],
        [0.5 * dt**3, dt**2, dt],
        [0.5 * dt**2, dt, 1.0],
    ]


def kf_predict(
    x: FloatArray, P: FloatArray, F: FloatArray, Q: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman predict: x = F x, P = F P F' + Q (filterpy's KalmanFilter.predict, bit for bit)."""
    return np.dot(F, x), np.dot(np.dot(F, P), F.T) + Q


def switch_matrix(dt: float, sojourn_cv_s: float, sojourn_ca_s: float) -> FloatArray:
    """Mode transition probabilities M[i, j] = P(j at t + dt | i at t) for mean times
    sojourn_cv_s and sojourn_ca_s spent in each mode (a continuous-time Markov chain).
    """
    p = 1.0 - math.exp(-dt / sojourn_cv_s)
    q = 1.0 - math.exp(-dt / sojourn_ca_s)
    return np.array([[1.0 - p, p], [q, 1.0 - q]])


def combine(
    xs: tuple[FloatArray, ...], Ps: tuple[FloatArray, ...], mu: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Moment-matched mixture of the two modes: x = sum mu_j x_j, P = sum mu_j (P_j + dx dx'),
    whose spread term is mu_0 mu_1 (x_0 - x_1)(x_0 - x_1)' for two components.
    """
    m0, m1 = float(mu[0]), float(mu[1])
    d = xs[0] - xs[1]
    # np.outer(d, d) is this product (d[:, None] * d[None, :]), without its argument handling
    return m0 * xs[0] + m1 * xs[1], m0 * Ps[0] + m1 * Ps[1] + (m0 * m1) * (d[:, None] * d)


def mix(
    xs: tuple[FloatArray, ...], Ps: tuple[FloatArray, ...], mu: FloatArray, M: FloatArray
) -> tuple[tuple[FloatArray, ...], tuple[FloatArray, ...], FloatArray]:
    """IMM interaction: each mode's initial (x0_j, P0_j) and predicted probabilities cbar."""
    cbar = mu @ M  # cbar_j = sum_i M_ij mu_i
    w = (M * mu[:, None]) / np.maximum(cbar, 1e-300)  # w[i, j] = mu_{i|j}
    x0s, P0s = [], []
    for j in range(len(xs)):
        x0, P0 = combine(xs, Ps, w[:, j])
        x0s.append(x0)
        P0s.append(P0)
    return tuple(x0s), tuple(P0s), cbar


class ImmFilter:
    """Predict / update of the two-mode IMM through one filterpy KalmanFilter (no state)."""

    def __init__(
        self, cv_accel_psd: float, ca_jerk_psd: float, sojourn_cv_s: float, sojourn_ca_s: float
    ) -> None:
        self._psd = (cv_accel_psd, ca_jerk_psd)
        self._sojourn = (sojourn_cv_s, sojourn_ca_s)
        self._kf = KalmanFilter(dim_x=6, dim_z=2)
        self._kf.H = H_POS
        # the switch matrix and (F, Q) per mode, by dt: steps repeat (scan and publish
        # periods), and building them dominates the cost otherwise; cached arrays are never
        # written to
        self._models: dict[float, tuple[FloatArray, tuple[tuple[FloatArray, FloatArray], ...]]]
        self._models = {}

    def _model(self, dt: float) -> tuple[FloatArray, tuple[tuple[FloatArray, FloatArray], ...]]:
        model = self._models.get(dt)
        if model is None:
            if len(self._models) >= 256:
                self._models.clear()
            per_mode = tuple(
                (transition(dt, ca), process_noise(dt, ca, self._psd[j]))
                for j, ca in enumerate((False, True))
            )
            model = (switch_matrix(dt, *self._sojourn), per_mode)
            self._models[dt] = model
        return model

    def predict(self, m: Modes, dt: float) -> Modes:
        """Mix, then predict each mode dt ahead (mu: the predicted mode probabilities)."""
        if dt <= 0.0:
            return m
        M, models = self._model(dt)
        x0s, P0s, cbar = mix(*m, M)
        out_x, out_P = [], []
        for j, (F, Q) in enumerate(models):
            x, P = kf_predict(x0s[j], P0s[j], F, Q)
            out_x.append(x)
            out_P.append(0.5 * (P + P.T))
        return Modes(tuple(out_x), tuple(out_P), cbar)

    def update(self, m: Modes, z: FloatArray, R: FloatArray) -> Modes:
        """Update every mode with the detection z (2,), noise R (2, 2); mode probabilities
        follow their likelihoods."""
        kf = self._kf
        out_x, out_P, loglik = [], [], []
        for xj, Pj in zip(m.xs, m.Ps, strict=True):
            y, S = innovation(xj, Pj, z, R)
            _, logdet = np.linalg.slogdet(2.0 * math.pi * S)
            loglik.append(-0.5 * (float(y @ np.linalg.solve(S, y)) + logdet))
            kf.x, kf.P = xj.copy(), Pj.copy()
            kf.update(z, R=R)
            out_x.append(kf.x.copy())
            out_P.append(0.5 * (kf.P + kf.P.T))
        ll = np.array(loglik)
        post = m.mu * np.exp(ll - ll.max())  # log-sum-exp guard against underflow
        total = float(post.sum())
        if not (total > 0.0 and np.isfinite(total)):
            # every mode's likelihood underflowed (or was NaN): keep the prior probabilities
            return Modes(tuple(out_x), tuple(out_P), m.mu)
        return Modes(tuple(out_x), tuple(out_P), post / total)
