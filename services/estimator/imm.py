"""Interacting multiple models for one obstacle: constant velocity + constant acceleration.

Both modes share the state [x, vx, ax, y, vy, ay] (filterpy's order_by_dim); the CV mode
holds the acceleration at zero. Mixing and combination follow Bar-Shalom's IMM; the
per-mode predict and update run through `kf_predict` and `kf_update`, the same equations as
filterpy's KalmanFilter.predict and .update without its object overhead (the estimator
predicts every track to every publish time: the hot path).

The two modes are held stacked, xs (2, 6) and Ps (2, 6, 6), and predicted together, and the
tracks published at one time are predicted together too (`predict_many`): each operation is
then one numpy call for all (a call's overhead, ~1 us, is most of its cost on 6 x 6 arrays).
Entry by entry the arithmetic is the one-by-one one: elementwise operations broadcast, and a
stacked matmul hands each matrix to the same BLAS routine, with the same arguments, as np.dot
does on one (tests/test_estimator_tracks.py holds them equal bit for bit).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]

# (switch matrix, F, Q) kept by dt, at most (ImmFilter._model)
MAX_MODELS = 1024
H_POS = np.array([[1.0, 0, 0, 0, 0, 0], [0, 0, 0, 1.0, 0, 0]])  # a detection sees x, y
_I6 = np.eye(6)


class Modes(NamedTuple):
    """An IMM belief: each mode's mean xs[j] (6,) and covariance Ps[j] (6, 6), modes (CV, CA),
    stacked (xs: (2, 6), Ps: (2, 6, 6)), and the mode probabilities mu (2,)."""

    xs: FloatArray
    Ps: FloatArray
    mu: FloatArray


def innovation(
    x: FloatArray, P: FloatArray, z: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """A detection z (2,) against the Gaussian (x, P): y = z - H x (2,), S = H P H' + R (2, 2);
    of one (x: (6,), P: (6, 6)) or of a stack of them (x: (k, 6), P: (k, 6, 6); y: (k, 2),
    S: (k, 2, 2)). H picks x and y out of the state: H x and H P H' are those entries,
    exactly, however the products are summed (so a stack's are the ones formed alone)."""
    return z - np.matmul(H_POS, x[..., None])[..., 0], np.matmul(H_POS, P) @ H_POS.T + R


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
    """Kalman predict: x = F x, P = F P F' + Q (filterpy's KalmanFilter.predict, bit for bit),
    of one belief (x: (6,), P, F, Q: (6, 6)) or of a stack of them (x: (k, 6), the others
    (k, 6, 6)): matmul runs BLAS's gemv and gemm on each, as np.dot does on one."""
    return np.matmul(F, x[..., None])[..., 0], np.matmul(F, P) @ F.swapaxes(-1, -2) + Q


def switch_matrix(dt: float, sojourn_cv_s: float, sojourn_ca_s: float) -> FloatArray:
    """Mode transition probabilities M[i, j] = P(j at t + dt | i at t) for mean times
    sojourn_cv_s and sojourn_ca_s spent in each mode (a continuous-time Markov chain).
    """
    p = 1.0 - math.exp(-dt / sojourn_cv_s)
    q = 1.0 - math.exp(-dt / sojourn_ca_s)
    return np.array([[1.0 - p, p], [q, 1.0 - q]])


def combine(xs: FloatArray, Ps: FloatArray, mu: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Moment-matched mixture of the two modes: x = sum mu_j x_j, P = sum mu_j (P_j + dx dx'),
    whose spread term is mu_0 mu_1 (x_0 - x_1)(x_0 - x_1)' for two components.

    xs: (..., 2, 6), Ps: (..., 2, 6, 6), mu: (..., 2) -> x: (..., 6), P: (..., 6, 6), over any
    leading (broadcast) dimensions: a stack of beliefs, or of weights for one belief (`mix`).
    """
    if xs.ndim == 2 and mu.ndim == 1:
        # one belief (a track gated or predicted alone): the same products and sums as the
        # broadcast form below, without its indexing (~2 us of ~11 a call)
        w0, w1 = mu.tolist()
        x0, x1 = xs
        d = x0 - x1
        return w0 * x0 + w1 * x1, w0 * Ps[0] + w1 * Ps[1] + (w0 * w1) * (d[:, None] * d)
    m0, m1 = mu[..., 0, None], mu[..., 1, None]  # (..., 1)
    x0, x1 = xs[..., 0, :], xs[..., 1, :]
    d = x0 - x1
    x = m0 * x0 + m1 * x1
    m0, m1 = m0[..., None], m1[..., None]  # (..., 1, 1)
    # np.outer(d, d) is this product (d[:, None] * d[None, :]), without its argument handling
    spread = d[..., :, None] * d[..., None, :]
    return x, m0 * Ps[..., 0, :, :] + m1 * Ps[..., 1, :, :] + (m0 * m1) * spread


def mix(
    xs: FloatArray, Ps: FloatArray, mu: FloatArray, M: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """IMM interaction: each mode's initial (x0_j, P0_j), stacked ((..., 2, 6), (..., 2, 6,
    6)), and the predicted probabilities cbar (..., 2), of one belief (xs: (2, 6), Ps: (2, 6,
    6), mu: (2,), M: (2, 2)) or a stack of them (a leading dimension on each).

    (x0_j, P0_j) is `combine` of the two modes with the weights w[:, j]: one call for both j
    (broadcast over them; the spread they share is formed once)."""
    cbar = (mu[..., None, :] @ M)[..., 0, :]  # cbar_j = sum_i M_ij mu_i
    # w[i, j] = mu_{i|j}
    w = (M * mu[..., :, None]) / np.maximum(cbar, 1e-300)[..., None, :]
    x0s, P0s = combine(xs[..., None, :, :], Ps[..., None, :, :, :], w.swapaxes(-1, -2))
    return x0s, P0s, cbar


class ImmFilter:
    """Predict / update of the two-mode IMM (no state; the models kept by dt, the beliefs
    stacked last kept with their stack)."""

    def __init__(
        self, cv_accel_psd: float, ca_jerk_psd: float, sojourn_cv_s: float, sojourn_ca_s: float
    ) -> None:
        self._psd = (cv_accel_psd, ca_jerk_psd)
        self._sojourn = (sojourn_cv_s, sojourn_ca_s)
        # the switch matrix and (F, Q) of both modes stacked, by dt: steps repeat (scan and
        # publish periods), and building them dominates the cost otherwise; cached arrays are
        # never written to. A mission asks a few hundred distinct dt (coasting tracks, float
        # noise in t - stamp): MAX_MODELS keeps them all (~1 KB each)
        self._models: dict[float, tuple[FloatArray, FloatArray, FloatArray]] = {}
        # the beliefs predict_many stacked last, and their stack: the estimator predicts the
        # same tracks to every publish time until the next scan, so most calls would stack
        # the very same arrays again (~8 us of ~75 for three tracks)
        self._stacked: tuple[tuple[Modes, ...], Modes] = ((), Modes(*(np.empty(0),) * 3))

    def _model(self, dt: float) -> tuple[FloatArray, FloatArray, FloatArray]:
        model = self._models.get(dt)
        if model is None:
            if len(self._models) >= MAX_MODELS:
                self._models.clear()
            cv, ca = self._psd
            # np.array of a list of equal arrays stacks them, at a fraction of np.stack's cost
            F = np.array((transition(dt, False), transition(dt, True)))
            Q = np.array((process_noise(dt, False, cv), process_noise(dt, True, ca)))
            model = (switch_matrix(dt, *self._sojourn), F, Q)
            self._models[dt] = model
        return model

    def predict(self, m: Modes, dt: float) -> Modes:
        """Mix, then predict each mode dt ahead (mu: the predicted mode probabilities)."""
        if dt <= 0.0:
            return m
        return self._predicted(m, *self._model(dt))

    def predict_many(self, ms: Sequence[Modes], dts: Sequence[float]) -> Modes:
        """`predict` of each belief ms[k] dt[k] > 0 ahead, stacked: xs (k, 2, 6), Ps (k, 2, 6,
        6), mu (k, 2), the same floats as one by one (every operation acts on each belief
        alone), for a numpy call's overhead per operation, not per belief."""
        models = [self._model(dt) for dt in dts]
        return self._predicted(
            self._stack(ms), *(np.array([mod[i] for mod in models]) for i in range(3))
        )

    def _stack(self, ms: Sequence[Modes]) -> Modes:
        """The beliefs ms stacked (xs (k, 2, 6), Ps (k, 2, 6, 6), mu (k, 2)): the last stack
        again when ms are the very beliefs stacked last (a belief's arrays are never written
        to, nor are a stack's)."""
        last, stack = self._stacked
        if len(last) == len(ms) and all(a is b for a, b in zip(last, ms, strict=True)):
            return stack
        # np.array of a list of equal arrays stacks them, at a fraction of np.stack's cost
        stack = Modes(*(np.array([mk[i] for mk in ms]) for i in range(3)))
        self._stacked = (tuple(ms), stack)
        return stack

    @staticmethod
    def _predicted(m: Modes, M: FloatArray, F: FloatArray, Q: FloatArray) -> Modes:
        """Mix, then predict each mode with its F, Q ((..., 2, 6, 6)); M (..., 2, 2)."""
        x0s, P0s, cbar = mix(*m, M)
        x, P = kf_predict(x0s, P0s, F, Q)
        return Modes(x, 0.5 * (P + P.swapaxes(-1, -2)), cbar)

    def update(self, m: Modes, z: FloatArray, R: FloatArray) -> Modes:
        """Update every mode with the detection z (2,), noise R (2, 2); mode probabilities
        follow their likelihoods. Of one belief, or of a stack of them (xs (k, 2, 6), Ps (k,
        2, 6, 6), mu (k, 2); z (k, 2), R (k, 2, 2)): the same floats as one by one."""
        # every mode's innovations, log-determinants and S^-1 y at once: numpy's linalg runs
        # the same LAPACK routine on each matrix of a stack as on one alone
        Rs = R[..., None, :, :]  # the detection's noise, for each mode
        ys, Ss = innovation(m.xs, m.Ps, z[..., None, :], Rs)
        _, logdets = np.linalg.slogdet(2.0 * math.pi * Ss)
        sols = np.linalg.solve(Ss, ys[..., None])[..., 0]
        xs, Ps = kf_update(m.xs, m.Ps, ys, Rs)
        Ps = 0.5 * (Ps + Ps.swapaxes(-1, -2))
        if m.mu.ndim == 1:
            return Modes(xs, Ps, _posterior_mu(m.mu, ys, sols, logdets))
        mus = [_posterior_mu(*one) for one in zip(m.mu, ys, sols, logdets, strict=True)]
        return Modes(xs, Ps, np.array(mus))


def _posterior_mu(
    mu: FloatArray, ys: FloatArray, sols: NDArray[np.floating[Any]], logdets: FloatArray
) -> FloatArray:
    """The mode probabilities mu (2,) after a detection: each mode's likelihood from its
    innovation ys[j], S^-1 ys[j] (sols[j]) and log det(2 pi S) (logdets[j])."""
    loglik = [-0.5 * (float(ys[j] @ sols[j]) + logdets[j]) for j in range(len(ys))]
    ll = np.array(loglik)
    post = mu * np.exp(ll - ll.max())  # log-sum-exp guard against underflow
    total = float(post.sum())
    if not (total > 0.0 and np.isfinite(total)):
        # every mode's likelihood underflowed (or was NaN): keep the prior probabilities
        return mu
    return post / total


def kf_update(
    xs: FloatArray, Ps: FloatArray, ys: FloatArray, R: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Kalman update of each belief of a stack (xs: (k, 6), Ps: (k, 6, 6)) with its
    innovation ys (k, 2) = z - H x of a detection of noise R ((2, 2), or one per belief),
    H = H_POS: filterpy's KalmanFilter.update, Joseph form, bit for bit (matmul runs BLAS's
    gemv and gemm on each belief, as np.dot does on one; numpy's inv the same LAPACK
    routine)."""
    HT = H_POS.T
    PHT = np.matmul(Ps, HT)
    K = np.matmul(PHT, np.linalg.inv(np.matmul(H_POS, PHT) + R))  # K = P H' S^-1
    x = xs + np.matmul(K, ys[..., None])[..., 0]
    I_KH = _I6 - np.matmul(K, H_POS)
    # P = (I - K H) P (I - K H)' + K R K'
    KT = K.swapaxes(-1, -2)
    return x, np.matmul(np.matmul(I_KH, Ps), I_KH.swapaxes(-1, -2)) + np.matmul(K @ R, KT)
