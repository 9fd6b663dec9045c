"""Vehicle-state filters (filterpy EKF or UKF) over the current-carried unicycle, as pure x, P
maps."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from common.config.estimator import EstimatorConfig
from common.scalar import wrap_angle
from services.estimator.filterpy_lazy import MerweScaledSigmaPoints, UnscentedKalmanFilter
from services.estimator.measurements import Observation
from services.estimator.unicycle import (
    DIM_X,
    circular_mean,
    fx,
    jacobian_at,
    jacobian_fixed,
    process_noise_at,
    process_noise_fixed,
    residual_x,
)

FloatArray = NDArray[np.float64]

# Sub-steps of one prediction at most, whatever dt and max_predict_dt_s: the work of one
# prediction stays bounded (the estimator never predicts further than 60 s, 600 default
# sub-steps); beyond this the sub-steps just get longer.
MAX_SUBSTEPS = 1000
# Sub-step lengths whose fixed model parts a filter keeps (_SubstepPredict.fixed)
MAX_SUBSTEP_LENGTHS = 256


class VehicleFilter(Protocol):
    """Predict and update a Gaussian belief (x, P); inputs are never modified."""

    def predict(self, x: FloatArray, P: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
        """The belief dt seconds later (dt <= 0 returns it unchanged)."""
        ...

    def update(
        self, x: FloatArray, P: FloatArray, obs: Observation
    ) -> tuple[FloatArray, FloatArray]:
        """The belief after fusing one observation (services/estimator/measurements.py)."""
        ...


def _substeps(dt: float, max_dt: float) -> tuple[int, float]:
    # equal sub-steps, a pure function of dt: replaying a prediction repeats it exactly
    ratio = dt / max_dt
    n = max(1, math.ceil(ratio - 1e-9)) if ratio < MAX_SUBSTEPS else MAX_SUBSTEPS
    return n, dt / n


def _tidy(x: FloatArray, P: FloatArray) -> tuple[FloatArray, FloatArray]:
    x = np.array(x, dtype=np.float64).reshape(DIM_X)
    x[2] = wrap_angle(float(x[2]))
    return x, 0.5 * (P + P.T)


class _SubstepPredict:
    """The predict both filters share: the belief unchanged (a copy) for dt <= 0, else what
    the filter's `advance` makes of a copy in n equal sub-steps of h (_substeps)."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        self._q = (
            cfg.accel_psd_m2_s3,
            cfg.yaw_accel_psd_rad2_s3,
            cfg.current_psd_m2_s3,
            cfg.position_psd_m2_s,
            cfg.sway_std_mps,
            cfg.sway_tau_s,
        )
        self._tau = cfg.sway_tau_s
        self._max_dt = cfg.max_predict_dt_s
        # the Jacobian's and Q's entries that depend on h alone, by h: a mission's sub-steps
        # take a few tens of lengths (fix periods split, with float noise); never written to
        self._fixed: dict[float, tuple[FloatArray, FloatArray]] = {}

    def fixed(self, h: float) -> tuple[FloatArray, FloatArray]:
        """(jacobian_fixed, process_noise_fixed) of a sub-step of h seconds, kept."""
        got = self._fixed.get(h)
        if got is None:
            if len(self._fixed) >= MAX_SUBSTEP_LENGTHS:
                self._fixed.clear()
            got = (jacobian_fixed(h, self._tau), process_noise_fixed(h, *self._q))
            self._fixed[h] = got
        return got

    def predict(self, x: FloatArray, P: FloatArray, dt: float) -> tuple[FloatArray, FloatArray]:
        if dt <= 0.0:
            return x.copy(), P.copy()
        n, h = _substeps(dt, self._max_dt)
        return self.advance(x.copy(), P.copy(), n, h)

    def advance(
        self, x: FloatArray, P: FloatArray, n: int, h: float
    ) -> tuple[FloatArray, FloatArray]:
        """The belief (x, P), the callee's to modify, n sub-steps of h seconds later."""
        raise NotImplementedError


class EkfVehicleFilter(_SubstepPredict):
    """Extended Kalman filter: filterpy's ExtendedKalmanFilter equations (predict with the
    nonlinear unicycle fx, update in Joseph form), the same numpy calls in the same order
    without its object: the filter saves no prior or posterior copies, no deepcopy of z, and
    its scipy inverse skips scipy's input checks for one of its own (`_inverse`).
    tests/test_estimator_filters.py holds both to filterpy's bit for bit."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        super().__init__(cfg)
        self._I = np.eye(DIM_X)

    def advance(
        self, x: FloatArray, P: FloatArray, n: int, h: float
    ) -> tuple[FloatArray, FloatArray]:
        F0, Q0 = self.fixed(h)
        q_accel, tau = self._q[0], self._tau
        for _ in range(n):
            # P = F P F' + Q, F = d fx / d s and Q (unicycle.py) linearised at the prior
            F = jacobian_at(F0.copy(), x, h)
            Q = process_noise_at(Q0.copy(), x, h, q_accel)
            x = fx(x, h, tau)
            P = np.dot(F, P).dot(F.T) + Q
        return _tidy(x, P)

    def update(
        self, x: FloatArray, P: FloatArray, obs: Observation
    ) -> tuple[FloatArray, FloatArray]:
        R = obs.R
        H = obs.H(x)
        PHT = np.dot(P, H.T)
        K = PHT.dot(_inverse(np.dot(H, PHT) + R))  # K = P H' S^-1, S = H P H' + R
        x = x + np.dot(K, obs.residual(obs.z, obs.hx(x)))
        # P = (I - K H) P (I - K H)' + K R K' (Joseph form)
        I_KH = self._I - np.dot(K, H)
        return _tidy(x, np.dot(I_KH, P).dot(I_KH.T) + np.dot(K, R).dot(K.T))


def _inverse(S: FloatArray) -> FloatArray:
    """scipy.linalg.inv(S) (filterpy's EKF inverse): the same LAPACK result, the same
    ValueError on a non-finite S, its finiteness checked here on Python floats (scipy's own
    check costs more than the inverse of a 5 x 5)."""
    if not all(map(math.isfinite, S.ravel().tolist())):
        raise ValueError("array must not contain infs or NaNs")
    return scipy.linalg.inv(S, check_finite=False)


class UkfVehicleFilter(_SubstepPredict):
    """Unscented Kalman filter (filterpy UnscentedKalmanFilter, Merwe scaled sigma points)."""

    def __init__(self, cfg: EstimatorConfig) -> None:
        super().__init__(cfg)
        points = MerweScaledSigmaPoints(
            DIM_X, alpha=cfg.ukf_alpha, beta=cfg.ukf_beta, kappa=cfg.ukf_kappa, subtract=residual_x
        )
        self._ukf = UnscentedKalmanFilter(
            dim_x=DIM_X,
            dim_z=4,
            dt=cfg.max_predict_dt_s,
            hx=lambda s: s[:4],  # each update passes its observation's own model
            fx=lambda s, dt: fx(s, dt, cfg.sway_tau_s),
            points=points,
            x_mean_fn=circular_mean,
            residual_x=residual_x,
        )

    def advance(
        self, x: FloatArray, P: FloatArray, n: int, h: float
    ) -> tuple[FloatArray, FloatArray]:
        ukf = self._ukf
        ukf.x, ukf.P = x, P
        Q0 = self.fixed(h)[1]
        for _ in range(n):
            ukf.Q = process_noise_at(Q0.copy(), ukf.x, h, self._q[0])  # process_noise
            ukf.predict(dt=h)
            ukf.x, ukf.P = _tidy(ukf.x, ukf.P)
        return ukf.x.copy(), ukf.P.copy()

    def update(
        self, x: FloatArray, P: FloatArray, obs: Observation
    ) -> tuple[FloatArray, FloatArray]:
        ukf = self._ukf
        ukf.x, ukf.P = x.copy(), P.copy()
        # sigma points of this belief (dt = 0), so the update never depends on an earlier
        # predict call: a rolled-back belief can be updated directly
        ukf.compute_process_sigmas(0.0)
        ukf.residual_z = obs.residual
        angle = obs.angle
        ukf.z_mean = lambda sigmas, weights: circular_mean(sigmas, weights, angle)
        ukf.update(obs.z, R=obs.R, hx=obs.hx)
        return _tidy(ukf.x, ukf.P)


def make_vehicle_filter(cfg: EstimatorConfig) -> VehicleFilter:
    """The configured vehicle filter, chosen once."""
    if cfg.vehicle_filter == "ukf":
        return UkfVehicleFilter(cfg)
    return EkfVehicleFilter(cfg)
