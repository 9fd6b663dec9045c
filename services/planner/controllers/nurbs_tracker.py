"""The NURBS tracking controller (the paper's method): curvature feed-forward, delay-aware.

Law (Serret-Frenet path following, e.g. Samson 1995; Lekkas & Fossen 2012 for the
look-ahead form). With s the projection of the (predicted) pose on the path, e_y the
lateral error (> 0 left), e_theta = theta - theta_p(s) and kappa(s) the signed curvature:

    s_dot   = v cos(e_theta) / (1 - kappa e_y)
    chi     = -atan(e_y / Delta)                  desired approach angle, Delta = look-ahead
    w       = kappa s_dot                         curvature feed-forward (= v kappa on the path)
              + dchi/de_y * v sin(e_theta)        keeps the approach angle consistent
              - k_h wrap_angle(e_theta - chi)           heading feedback

With z = e_theta - chi, unsaturated and with the true speed v, this gives dz/dt = -k_h z
exactly, and with z = 0 the cross-track error obeys de_y/dt = -v e_y / sqrt(Delta^2 + e_y^2)
(V = e_y^2 / 2 decreases). That is a cascade of two stable systems, the e_y part being
input-to-state stable in z (|sin(chi + z) - sin(chi)| <= |z|), so both errors converge.

Speed: v_ref, reduced so that the feed-forward for the tightest curvature within
preview_s ahead uses at most `curvature_budget` of the eq. (11) yaw-rate bound; the rest is
left to the feedback. Turning radius: |w| <= v_cmd / R_min (eqs. 19-20) on top of eq. (11).

Delay compensation: before computing, the pose is predicted forward by `latency_s` (the
estimate's age plus the expected downlink delay, supplied by the caller) with the unicycle
model, eq. (7), at constant (v, w).

Gains (common/config/controller.py NurbsGains): Delta = max(3 m, 1.5 s * v), k_h = 1.2 /s,
budget 0.7, preview 3 s.
"""

from __future__ import annotations

import math

from common.config.controller import NurbsGains
from common.scalar import clamp, wrap_angle
from services.planner.controllers.arc_reference import ArcLengthReference
from services.planner.controllers.base import Limits, Pose, path_errors, predict_pose

_PREVIEW_SAMPLES = 7  # curvature samples over the preview window (incl. both ends)


class NurbsTracker:
    """Curvature feed-forward + look-ahead feedback path follower with delay compensation."""

    name = "nurbs"

    def __init__(self, gains: NurbsGains, limits: Limits, *, compensate_delay: bool = True):
        self.gains = gains
        self.limits = limits
        self.compensate_delay = compensate_delay
        self._s_hint: float | None = None
        self.last_errors = (0.0, 0.0)  # (e_y, e_theta) of the last call, for logs and tests

    def reset(self) -> None:
        self._s_hint = None
        self.last_errors = (0.0, 0.0)

    def speed_for(self, ref: ArcLengthReference, s: float) -> float:
        """v_ref reduced so that v |kappa| <= budget * w_max over the preview window."""
        lim, g = self.limits, self.gains
        v = min(ref.v_ref, lim.v_max)
        horizon = min(ref.length, s + v * g.preview_s)
        k_max = 0.0
        for i in range(_PREVIEW_SAMPLES):
            si = s + (horizon - s) * i / (_PREVIEW_SAMPLES - 1)
            k_max = max(k_max, abs(ref.curvature_at_s(si)))
        w_room = g.curvature_budget * min(lim.w_max, -lim.w_min)
        if k_max * v > w_room:
            v = w_room / k_max
        return clamp(v, lim.v_min, lim.v_max)

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]:
        """(v, w) for the pose, saturated to eq. (11) and |w| <= v / R_min."""
        if self.compensate_delay and latency_s > 0.0:
            pose = predict_pose(pose, latency_s)
        x, y, theta, v_meas, _ = pose
        lim, g = self.limits, self.gains
        s = ref.closest_s(x, y, self._s_hint)
        self._s_hint = s
        e_y, e_th = path_errors(x, y, theta, ref, s)
        self.last_errors = (e_y, e_th)
        kappa = ref.curvature_at_s(s)
        v_cmd = self.speed_for(ref, s)
        # kinematic terms use the measured speed: the vehicle turns at w / v_actual
        v_k = max(v_meas, 0.0)
        delta = max(g.lookahead_m, g.lookahead_time_s * v_cmd)
        chi = -math.atan(e_y / delta)
        denom = max(1.0 - kappa * e_y, 0.2)  # guard the Frenet singularity at the centre
        w_ff = kappa * v_k * math.cos(e_th) / denom  # curvature feed-forward
        dchi = -delta / (delta * delta + e_y * e_y) * v_k * math.sin(e_th)
        w = w_ff + dchi - g.k_heading_ps * wrap_angle(e_th - chi)
        # turning radius >= R_min (eqs. 19-20), then eq. (11)
        w_r = v_cmd / lim.r_min
        w = clamp(w, -w_r, w_r)
        return lim.saturate(v_cmd, w)
