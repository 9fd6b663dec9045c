"""ImmuneFuzzyPid: the paper's second baseline, an immune fuzzy PID on the heading error.

Error: cross-track and heading combined through a look-ahead (line-of-sight) angle,

    e = wrap_angle(chi - e_theta),  chi = -atan(e_y / L)

i.e. the desired heading minus the actual one (rad; > 0 asks for a left turn).

Fuzzy PID (Mamdani, fuzzy.py): e and de/dt (de/dt filtered by the first-order lag of eq. (3),
the "virtual damping") are normalised to [-3, 3]; the three 49-rule tables give dKp, dKi,
dKd in [-3, 3], scaled to +- (dkp, dki, dkd) around the base gains (kp, ki, kd).

Immune feedback (the helper/suppressor T-cell model of Takahashi & Yamada, "Application of
an immune feedback mechanism to control systems", JSME Int. J. C, 1998, in the immune-PID
form u(k) = K [1 - eta f(u(k), du(k))] e(k) used by immune fuzzy PID controllers): the
whole PID output is scaled by

    K = K1 [1 - eta f(du)],   f(du) = 1 - exp(-du^2 / a)

with du the last change of the output (the suppressor signal grows with how hard the control
is moving), so K in (K1 (1 - eta), K1]: full gain when the command is steady, less gain when
it is changing fast, which damps oscillation.

Output w = K (Kp e + Ki int e dt + Kd de/dt), saturated to eq. (11) and to |w| <= v / R_min
(eqs. 19-20) at the speed the (predicted) pose has, which the plant enforces anyway
(conditional integration: the integral only grows when the output is not saturated in the
error's direction). No curvature feed-forward (the integral carries the steady turn on
curves): this is the published baseline.

Speed: the shared profile (speed.py: cruise cap, ramp, curvature slow-down, stop at the end),
as for the other two controllers, so that they differ in how they steer only. Gains in
FuzzyPidGains; delay compensation as for every controller (ControllerConfig.
delay_compensation).
"""

from __future__ import annotations

import math

from common.config.controller import FuzzyPidGains
from common.scalar import wrap_angle
from services.control.controllers.arc_reference import ArcLengthReference
from services.control.controllers.base import Pose, path_errors
from services.control.controllers.follower import PathFollower
from services.control.controllers.fuzzy import DKD_TABLE, DKI_TABLE, DKP_TABLE, MamdaniTables

_TABLES = MamdaniTables(DKP_TABLE, DKI_TABLE, DKD_TABLE)


class ImmuneFuzzyPid(PathFollower[FuzzyPidGains]):
    """Immune-regulated fuzzy self-tuning PID producing a yaw rate from the LOS error."""

    name = "fuzzy_pid"

    def reset(self) -> None:
        super().reset()
        self._t_prev: float | None = None
        self._e_prev = 0.0
        self._de = 0.0  # filtered de/dt
        self._integral = 0.0
        self._u_prev = 0.0
        self._du_prev = 0.0
        self.last_gains = (self.gains.kp_ps, self.gains.ki_ps2, self.gains.kd, 1.0)

    def command(
        self, t: float, pose: Pose, ref: ArcLengthReference, latency_s: float = 0.0
    ) -> tuple[float, float]:
        """(v, w): the profile speed and the immune fuzzy PID's yaw rate, saturated to eq. (11)
        and R_min."""
        g = self.gains
        pose, s = self.project(pose, ref, latency_s)
        x, y, theta, _, _ = pose
        e_y, e_th = path_errors(x, y, theta, ref, s)
        e = wrap_angle(-math.atan(e_y / g.lookahead_m) - e_th)
        dt = 0.0 if self._t_prev is None else max(0.0, t - self._t_prev)
        if dt > 0.0:
            de_raw = wrap_angle(e - self._e_prev) / dt
            # eq. (3): u_i = (dt e_i + T u_{i-1}) / (dt + T), a first-order lag on de/dt
            self._de = (dt * de_raw + g.de_filter_s * self._de) / (dt + g.de_filter_s)
        # fuzzy self-tuning of the PID gains
        d_kp, d_ki, d_kd = _TABLES.infer(3.0 * e / g.e_scale_rad, 3.0 * self._de / g.de_scale_rps)
        kp = max(0.0, g.kp_ps + float(d_kp) / 3.0 * g.dkp_ps)
        ki = max(0.0, g.ki_ps2 + float(d_ki) / 3.0 * g.dki_ps2)
        kd = max(0.0, g.kd + float(d_kd) / 3.0 * g.dkd)
        # immune regulation: K = K1 [1 - eta f(du)], f = 1 - exp(-du^2 / a)
        f = 1.0 - math.exp(-(self._du_prev * self._du_prev) / g.immune_a)
        k_imm = g.immune_k1 * (1.0 - g.immune_eta * f)
        integral = self._integral + e * dt
        u = k_imm * (kp * e + ki * integral + kd * self._de)
        v, w_cmd = self.finish(
            self.speed.command(t, ref, s, self.water_speed, self.current_speed), u
        )
        w = self.course_rate(w_cmd)  # the saturated u, in the law's units
        if w == u or (u > w) != (e > 0.0):  # conditional integration (anti-windup)
            self._integral = integral
        self._du_prev = w - self._u_prev
        self._u_prev = w
        self._e_prev = e
        self._t_prev = t
        self.last_gains = (kp, ki, kd, k_imm)
        return v, w_cmd
