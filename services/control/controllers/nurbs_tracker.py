"""The NURBS tracking controller: curvature feed-forward and look-ahead feedback, delay-aware.

The paper's method is the planner (cost map, graph path, a NURBS path within R_min), which
all three controllers share; it gives no tracking law. This one is tidelink's design: it
follows the NURBS path with the path's own curvature as feed-forward.

Law (Serret-Frenet path following, e.g. Samson 1995; Lekkas & Fossen 2012 for the
look-ahead form). With s the projection of the (predicted) pose on the path, e_y the
lateral error (> 0 left), e_theta = theta - theta_p(s) and kappa(s) the signed curvature:

    s_dot   = v cos(e_theta) / (1 - kappa e_y)
    chi     = -atan(e_y / Delta)                  desired approach angle, Delta = look-ahead
    w       = kappa s_dot                         curvature feed-forward (= v kappa on the path;
                                                  kappa read yaw_tau_s ahead, Limits.ahead)
              + dchi/de_y * v sin(e_theta)        keeps the approach angle consistent
              - k_h wrap_angle(e_theta - chi)           heading feedback

With z = e_theta - chi, unsaturated and with the true speed v, this gives dz/dt = -k_h z
exactly, and with z = 0 the cross-track error obeys de_y/dt = -v e_y / sqrt(Delta^2 + e_y^2)
(V = e_y^2 / 2 decreases). That is a cascade of two stable systems, the e_y part being
input-to-state stable in z (|sin(chi + z) - sin(chi)| <= |z|), so both errors converge.

Speed: the shared profile (speed.py: cruise cap, ramp, curvature slow-down, stop at the end),
as for the two baselines; what sets this controller apart is its steering. Turning radius:
|w| <= v / R_min (eqs. 19-20) at the speed the (predicted) pose has, as the plant enforces,
on top of eq. (11).

Delay compensation (ControllerConfig.delay_compensation, the same for every controller):
before computing, the pose is predicted forward by `latency_s` (the estimate's age plus the
expected downlink delay, supplied by the caller) with the unicycle model, eq. (7), at
constant (v, w).

Gains (common/config/controller.py NurbsGains): Delta = max(3 m, 1.5 s * v), k_h = 1.2 /s.
"""

from __future__ import annotations

import math

from common.config.controller import NurbsGains
from common.scalar import wrap_angle
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Pose, path_errors
from services.control.controllers.follower import PathFollower


class NurbsTracker(PathFollower[NurbsGains]):
    """Curvature feed-forward + look-ahead feedback path follower with delay compensation."""

    name = "nurbs"

    def reset(self) -> None:
        super().reset()
        self.last_errors = (0.0, 0.0)  # (e_y, e_theta) of the last call, for logs and tests

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]:
        """(v, w) for the pose, saturated to eq. (11) and |w| <= v / R_min."""
        pose, s = self.project(pose, ref, latency_s)
        x, y, theta, v_meas, _ = pose
        g = self.gains
        e_y, e_th = path_errors(x, y, theta, ref, s)
        self.last_errors = (e_y, e_th)
        kappa = ref.curvature_at_s(self.limits.ahead(s, v_meas, ref.length))
        cx, cy = self.current  # current_speed, written out: a rollout asks at every entry
        v_cmd = self.speed.command(t, ref, s, self.water_speed, math.hypot(cx, cy))
        # kinematic terms use the measured speed (over ground): the vehicle turns at w / v;
        # max(a, b) written out below as b if b > a else a (the same floats, NaN and -0.0
        # included)
        v_k = 0.0 if 0.0 > v_meas else v_meas
        delta = g.lookahead_time_s * v_cmd
        if not delta > g.lookahead_m:
            delta = g.lookahead_m
        chi = -math.atan(e_y / delta)
        denom = 1.0 - kappa * e_y
        if 0.2 > denom:  # guard the Frenet singularity at the centre
            denom = 0.2
        w_ff = kappa * v_k * math.cos(e_th) / denom  # curvature feed-forward
        dchi = -delta / (delta * delta + e_y * e_y) * v_k * math.sin(e_th)
        w = w_ff + dchi - g.k_heading_ps * wrap_angle(e_th - chi)
        # eq. (11), and the turning radius >= R_min (eqs. 19-20) at the speed through the water
        return self.finish(v_cmd, w)
