"""Backstepping: the Kanayama et al. (1990) tracking law, the paper's first baseline.

Y. Kanayama, Y. Kimura, F. Miyazaki, T. Noguchi, "A stable tracking control method for an
autonomous mobile robot", IEEE ICRA 1990. A reference posture p_r = (x_r, y_r, theta_r)
moves along the path with speed v_r and yaw rate w_r = v_r kappa(s_r). The error posture in
the vehicle frame is

    [e_x, e_y]^T = R(theta)^T [x_r - x, y_r - y]^T,   e_theta = wrap_angle(theta_r - theta)

and the law (their eq. 6) is

    v = v_r cos(e_theta) + k_x e_x
    w = w_r + v_r (k_y e_y + k_theta sin(e_theta))

with V = (e_x^2 + e_y^2) / 2 + (1 - cos e_theta) / k_y as a Lyapunov function (stable for
k_x, k_y, k_theta > 0, v_r > 0). Gains (BacksteppingGains): k_x = 0.5 /s, k_y = 0.04 /m^2,
k_theta = 0.4 /m = 2 sqrt(k_y) (their critical-damping choice), giving a linearised natural
frequency v_r sqrt(k_y) = 0.3 rad/s at v_r = 1.5 m/s.

Speed: v_r is the shared speed profile (speed.py: cruise cap, ramp, curvature slow-down,
stop at the end, evaluated where the vehicle projects on the path), as for the other two
controllers, so that they differ in how they steer only. The law's own speed output
v_r cos(e_theta) + k_x e_x may slow the vehicle down, never speed it up past the profile:
it is capped at v_r (uncapped, the k_x e_x term chased a reference that ran ahead up to
v_max).

Virtual reference point: s_r starts at the projection of the first pose and advances at v_r
with the caller's clock (Kanayama's time-parameterised reference), kept on a leash
s_proj <= s_r <= s_proj + max_lead_m so that a vehicle slowed down (or cut off by a network
outage) is not asked to chase a reference that ran away. At the end of the path v_r = 0.

Delay compensation (ControllerConfig.delay_compensation, the same for every controller): the
pose is predicted forward by latency_s with eq. (7); the virtual point keeps running on the
caller's clock and is not advanced further (the downlink part of latency_s is small next to
the leash). Saturation: eq. (11), and |w| <= v / R_min (eqs. 19-20) at the speed the
(predicted) pose has, which the plant enforces anyway.
"""

from __future__ import annotations

import math

from common.config.controller import BacksteppingGains
from common.scalar import clamp, wrap_angle
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Pose
from services.control.controllers.follower import PathFollower


class Backstepping(PathFollower[BacksteppingGains]):
    """Kanayama tracking of a virtual point running along the path at the profile speed."""

    name = "backstepping"

    def reset(self) -> None:
        super().reset()
        self._s_r: float | None = None
        self._t_prev: float | None = None
        self.last_errors = (0.0, 0.0, 0.0)  # (e_x, e_y, e_theta) of the last call

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]:
        """(v, w) from the Kanayama law at the profile speed, saturated to eq. (11) and R_min."""
        g = self.gains
        pose, s_proj = self.project(pose, ref, latency_s)
        x, y, theta, v_meas, _ = pose
        v_profile = self.speed.command(t, ref, s_proj, self.water_speed, self.current_speed)
        # the reference speed over ground: the profile's through the water, crabbing along the
        # path (= v_profile in calm water)
        v_r = u_r = self.ground_speed(v_profile, ref.heading_at_s(s_proj))
        # the virtual reference: advanced at v_r by the caller's clock, on a leash
        if self._s_r is None or self._t_prev is None:
            s_r = s_proj
        else:
            s_r = self._s_r + v_r * max(0.0, t - self._t_prev)
        s_r = clamp(s_r, s_proj, min(s_proj + g.max_lead_m, ref.length))
        self._s_r, self._t_prev = s_r, t
        s_eval = s_r
        if s_eval >= ref.length:
            v_r = 0.0  # the reference stopped at the end of the path
        xr, yr = ref.point_at_s(s_eval)
        th_r = ref.heading_at_s(s_eval)
        w_r = v_r * ref.curvature_at_s(self.limits.ahead(s_eval, v_meas, ref.length))
        # error posture in the vehicle frame (Kanayama eq. 3)
        c, sn = math.cos(theta), math.sin(theta)
        e_x = c * (xr - x) + sn * (yr - y)
        e_y = -sn * (xr - x) + c * (yr - y)
        e_th = wrap_angle(th_r - theta)
        self.last_errors = (e_x, e_y, e_th)
        # Kanayama eq. 6 over ground; the speed may fall below the profile, never rise above
        # it (the law's change of speed over ground is the change through the water)
        v = min(v_r * math.cos(e_th) + g.k_x_ps * e_x + (v_profile - u_r), v_profile)
        w = w_r + v_r * (g.k_y_pm2 * e_y + g.k_theta_pm * math.sin(e_th))
        return self.finish(v, w)
