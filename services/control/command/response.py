"""The planner's model of how the vehicle responds to a velocity command: eq. (7) with lags.

The planner predicts the vehicle forward (to the time a command takes effect, and along a
command sequence's horizon) with this model; it does not import the vehicle's plant (a
service never imports another), and needs less: the state is the pose and twist
(x, y, theta, v, w) of an estimate, and under a command (v_c, w_c) held over a step

    speed  dv/dt = clamp((v_c - v) / tau_v, -a_max, a_max)            the speed loop
    yaw    dw/dt = clamp((w_c' - w) / tau_w, -alpha_max, alpha_max),  w_c' = clamp(w_c, +-v/R_min)
    pose   x' = v cos(theta) + cx, y' = v sin(theta) + cy, theta' = w  eq. (7), carried by
                                                                  the current (cx, cy)

with |w| <= v / R_min at every instant (the plant enforces it: eq. (11)'s yaw-rate bound with
the R_min of eqs. (19)-(20)) and v within eq. (11). tau_v = m_eff / k_p is the speed loop's
time constant before its limits (common/config/vehicle.py: ~1 s), tau_w the yaw loop's.
Over the seconds a command spends in flight the lags matter (a speed step takes seconds), so
they are in (docs/notes/planner-response-model-lags.md). The current is the estimator's
(StateEstimate.current_x, current_y), held over the prediction (`with_current`).

Each step of at most MAX_STEP_S moves the twist by one Euler step of its (clamped) rate (a
lag shorter than the step reaches its goal within it) and the pose along the exact arc of
the step's mean twist: cheap, and the same floats in every runtime.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from common.config.vehicle import VehicleConfig

Pose = tuple[float, float, float, float, float]  # x, y, theta, v, w (m, m, rad, m/s, rad/s)

MAX_STEP_S = 0.05  # the integration step (s): a tenth of the yaw loop's time constant


@dataclass(frozen=True, kw_only=True, slots=True)
class ResponseModel:
    """First-order speed and yaw loops with their rate bounds, R_min and eq. (7)."""

    tau_v_s: float
    accel_max_mps2: float
    tau_w_s: float
    yaw_accel_max_rps2: float
    r_min_m: float
    v_max_mps: float
    w_min_rps: float
    w_max_rps: float
    current_mps: tuple[float, float] = (0.0, 0.0)  # (cx, cy), world frame

    @staticmethod
    def from_vehicle(cfg: VehicleConfig) -> ResponseModel:
        return ResponseModel(
            tau_v_s=cfg.mass_eff_kg / cfg.speed_kp_npmps,
            accel_max_mps2=cfg.accel_max_mps2,
            tau_w_s=cfg.yaw_tau_s,
            yaw_accel_max_rps2=cfg.yaw_accel_max_rps2,
            r_min_m=cfg.turn_radius_min_m,
            v_max_mps=cfg.v_max_mps,
            w_min_rps=cfg.w_min_rps,
            w_max_rps=cfg.w_max_rps,
        )

    def with_current(self, cx: float, cy: float) -> ResponseModel:
        """This model in a current (cx, cy) (m/s, world frame)."""
        if (cx, cy) == self.current_mps:
            return self
        return replace(self, current_mps=(cx, cy))

    def advance(
        self, pose: Pose, v_c: float, w_c: float, dt: float, twist_only: bool = False
    ) -> Pose:
        """The state dt seconds on under the command (v_c, w_c) held throughout; `twist_only`:
        its twist alone (x, y, theta left as they are: the twist's steps do not read them)."""
        n = math.ceil(dt / MAX_STEP_S - 1e-9)
        if n <= 0:
            return pose
        h = dt / n
        # a lag shorter than the step reaches its goal within the step, never beyond it
        tau_v, tau_w = self.tau_v_s, self.tau_w_s
        gain_v = 1.0 / (h if h > tau_v else tau_v)  # 1 / max(tau_v, h), written out
        gain_w = 1.0 / (h if h > tau_w else tau_w)
        a_max, alpha_max = self.accel_max_mps2, self.yaw_accel_max_rps2
        x, y, th, v, w = pose
        dx, dy = self.current_mps[0] * h, self.current_mps[1] * h  # drift over one step
        v_max, r_min = self.v_max_mps, self.r_min_m
        w_lo, w_hi = self.w_min_rps, self.w_max_rps
        cos, sin = math.cos, math.sin
        # the clamps are common.scalar.clamp written out (lo if x < lo else hi if x > hi
        # else x, the same floats), and so are max(a, b) (b if b > a else a) and min(a, b)
        # (b if b < a else a): this loop runs ~100k times a mission, and calling them took
        # a fifth of its time
        for _ in range(n):
            a = (v_c - v) * gain_v
            a = -a_max if a < -a_max else a_max if a > a_max else a
            v1 = v + h * a
            v1 = 0.0 if v1 < 0.0 else v_max if v1 > v_max else v1
            room = v1 / r_min  # the turn the fins allow at this speed
            wc = -room if w_c < -room else room if w_c > room else w_c
            dw = (wc - w) * gain_w
            dw = -alpha_max if dw < -alpha_max else alpha_max if dw > alpha_max else dw
            lo = -room if -room > w_lo else w_lo
            hi = room if room < w_hi else w_hi
            w1 = w + h * dw
            w1 = lo if w1 < lo else hi if w1 > hi else w1
            if twist_only:
                v, w = v1, w1
                continue
            # eq. (7) along the arc of the step's mean twist
            vm, wm = 0.5 * (v + v1), 0.5 * (w + w1)
            dth = wm * h
            if abs(dth) < 1e-9:
                x += vm * h * cos(th)
                y += vm * h * sin(th)
            else:
                r = vm / wm
                x += r * (sin(th + dth) - sin(th))
                y -= r * (cos(th + dth) - cos(th))
            th += dth
            x += dx
            y += dy
            v, w = v1, w1
        return x, y, th, v, w
