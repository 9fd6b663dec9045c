"""The estimator service: vehicle state (EKF/UKF) and obstacle tracks from delayed sensor data."""

from services.estimator.core import EstimatorCore

__all__ = ["EstimatorCore"]
