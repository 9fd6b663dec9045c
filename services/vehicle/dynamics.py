"""Vehicle plant: eq. (7) kinematics, eq. (14) surge drag, speed and yaw loops, one RK4 step.

State (Fossen-style names in the comments): eta = (x, y, theta), nu = (v, w), plus the speed
loop integrator z. Plain floats and `math` only: fast for scalar RK4 and bit-reproducible.

Turning radius: a rudder-steered AUV turns by the lift its fins make in the flow, so it
cannot turn tighter than its minimum radius R_min, whatever it is asked: |w| <= |v| / R_min
holds at every instant of the simulated truth. This is eq. (11)'s yaw-rate bound made
physical with the turning radius of eqs. (19)-(20) (the planner keeps its curves within
kappa < 1 / R_min, the controllers their commands within it; the plant enforces it). At rest
(v = 0) the vehicle cannot turn at all: there is no turning on the spot.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from common.config.vehicle import VehicleConfig
from common.scalar import clamp
from common.world.current import CurrentFn

# ITTC-1957 is fitted for Re >= ~1e5; below that (V -> 0) we hold Cf at its Re = 1e5 value.
# The drag still vanishes as V^2, so the guard only avoids log10(Re) <= 2 (a pole).
RE_MIN = 1.0e5

State = tuple[float, float, float, float, float, float]  # x, y, theta, v, w, z


@dataclass(frozen=True, kw_only=True, slots=True)
class PlantParams:
    """The constants the plant needs, precomputed once from a VehicleConfig."""

    half_rho_s: float  # 0.5 rho S of eq. (14)
    length_m: float
    nu_m2ps: float
    delta_cf: float
    c_pv: float
    mass_eff_kg: float
    thrust_min_n: float
    thrust_max_n: float
    kp: float
    ki: float
    int_band: float
    accel_max: float
    yaw_tau_s: float
    yaw_accel_max: float
    v_max: float
    w_min: float
    w_max: float
    r_min: float  # minimum turning radius R_min (eqs. (19)-(20)): |w| <= |v| / R_min

    @staticmethod
    def from_config(cfg: VehicleConfig) -> PlantParams:
        """The parameters of a `[vehicle]` section, eq. (14)'s 0.5 rho S folded into half_rho_s."""
        return PlantParams(
            half_rho_s=0.5 * cfg.rho_kgpm3 * cfg.wetted_area_m2,
            length_m=cfg.length_m,
            nu_m2ps=cfg.nu_m2ps,
            delta_cf=cfg.delta_cf,
            c_pv=cfg.c_pv,
            mass_eff_kg=cfg.mass_eff_kg,
            thrust_min_n=cfg.thrust_min_n,
            thrust_max_n=cfg.thrust_max_n,
            kp=cfg.speed_kp_npmps,
            ki=cfg.speed_ki_npm,
            int_band=cfg.speed_int_band_mps,
            accel_max=cfg.accel_max_mps2,
            yaw_tau_s=cfg.yaw_tau_s,
            yaw_accel_max=cfg.yaw_accel_max_rps2,
            v_max=cfg.v_max_mps,
            w_min=cfg.w_min_rps,
            w_max=cfg.w_max_rps,
            r_min=cfg.turn_radius_min_m,
        )


def friction_coefficient(speed: float, length_m: float, nu_m2ps: float) -> float:
    """ITTC-1957 line Cf = 0.075 / (log10(Re) - 2)^2 with Re = V L / nu (guarded at V -> 0)."""
    re = max(abs(speed) * length_m / nu_m2ps, RE_MIN)
    return 0.075 / (math.log10(re) - 2.0) ** 2


def drag_n(v: float, p: PlantParams) -> float:
    """eq. (14): R = 0.5 rho V^2 S (Cf + dCf + Cpv), signed so that it opposes v."""
    cf = friction_coefficient(v, p.length_m, p.nu_m2ps)
    return p.half_rho_s * v * abs(v) * (cf + p.delta_cf + p.c_pv)


def thrust_n(v_cmd: float, ff_n: float, v: float, z: float, p: PlantParams) -> tuple[float, float]:
    """Speed loop: T = R(v_cmd) + kp e + ki z, bounded; returns (T, dz/dt) with anti-windup.

    The drag feed-forward R(v_cmd) keeps the integrator near zero (it only trims model
    mismatch), so the loop settles fast. Anti-windup, written to keep the right-hand side
    continuous (a jump would cost RK4 its accuracy wherever a step straddles it):
    - the integrand is weighted by g(e) = exp(-(e / int_band)^2): integration happens only
      near the set point, so large speed changes do not wind the integrator up;
    - back-calculation (T - T_raw) / kp bleeds the integrator while the thrust saturates.
    """
    e = v_cmd - v
    t_raw = ff_n + p.kp * e + p.ki * z
    t = clamp(t_raw, p.thrust_min_n, p.thrust_max_n)
    x = e / p.int_band
    g = math.exp(-x * x)
    return t, g * (e + (t - t_raw) / p.kp)


def derivatives(
    s: State, v_cmd: float, w_cmd: float, ff_n: float, cx: float, cy: float, p: PlantParams
) -> State:
    """Time derivative of the state under a (v, w) command and a current (cx, cy)."""
    _, _, theta, v, w, z = s
    # eq. (7): no-sideslip unicycle, advected by the current
    dx = v * math.cos(theta) + cx
    dy = v * math.sin(theta) + cy
    # surge: m_eff dv/dt = T - R(v) (eq. 14), acceleration bounded
    t, dz = thrust_n(v_cmd, ff_n, v, z, p)
    dv = clamp((t - drag_n(v, p)) / p.mass_eff_kg, -p.accel_max, p.accel_max)
    # yaw: first-order towards the command, limited to what the fins can turn at this speed
    # (|w| <= |v| / R_min; the bound is continuous in v, so the right-hand side stays
    # continuous and RK4 keeps its order), yaw acceleration bounded
    w_room = abs(v) / p.r_min
    dw = clamp((clamp(w_cmd, -w_room, w_room) - w) / p.yaw_tau_s, -p.yaw_accel_max, p.yaw_accel_max)
    return dx, dy, w, dv, dw, dz


def rk4_step(
    s: State,
    h: float,
    v_cmd: float,
    w_cmd: float,
    p: PlantParams,
    *,
    t: float = 0.0,
    current: CurrentFn | None = None,
) -> State:
    """One classical RK4 step of length h from time t, with a command held over the step.

    `current(x, y, t)` is the water's velocity (world frame, m/s), evaluated at each stage's
    position and time; None is still water (no call at all). After the step, v and w are
    projected onto their eq. (11) bounds (v never reverses), and w onto the turning-radius
    bound |w| <= v / R_min at the new speed (the yaw loop follows a command already limited
    to it, so the projection only trims what a stage overshot or what a falling speed took
    away).
    """
    ff = drag_n(v_cmd, p)
    hh = 0.5 * h
    if current is None:
        k1 = derivatives(s, v_cmd, w_cmd, ff, 0.0, 0.0, p)
        k2 = derivatives(_axpy(s, hh, k1), v_cmd, w_cmd, ff, 0.0, 0.0, p)
        k3 = derivatives(_axpy(s, hh, k2), v_cmd, w_cmd, ff, 0.0, 0.0, p)
        k4 = derivatives(_axpy(s, h, k3), v_cmd, w_cmd, ff, 0.0, 0.0, p)
    else:
        k1 = derivatives(s, v_cmd, w_cmd, ff, *current(s[0], s[1], t), p)
        s2 = _axpy(s, hh, k1)
        k2 = derivatives(s2, v_cmd, w_cmd, ff, *current(s2[0], s2[1], t + hh), p)
        s3 = _axpy(s, hh, k2)
        k3 = derivatives(s3, v_cmd, w_cmd, ff, *current(s3[0], s3[1], t + hh), p)
        s4 = _axpy(s, h, k3)
        k4 = derivatives(s4, v_cmd, w_cmd, ff, *current(s4[0], s4[1], t + h), p)
    h6 = h / 6.0
    # s + h/6 (k1 + 2 k2 + 2 k3 + k4), component by component (a generator over zip cost
    # as much as a stage)
    x = s[0] + h6 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
    y = s[1] + h6 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
    theta = s[2] + h6 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
    v = s[3] + h6 * (k1[3] + 2.0 * k2[3] + 2.0 * k3[3] + k4[3])
    w = s[4] + h6 * (k1[4] + 2.0 * k2[4] + 2.0 * k3[4] + k4[4])
    z = s[5] + h6 * (k1[5] + 2.0 * k2[5] + 2.0 * k3[5] + k4[5])
    v = clamp(v, 0.0, p.v_max)
    w_room = v / p.r_min
    return x, y, theta, v, clamp(w, max(p.w_min, -w_room), min(p.w_max, w_room)), z


def _axpy(s: State, h: float, k: State) -> State:
    """s + h k for the 6-element state (an RK4 stage point)."""
    return (
        s[0] + h * k[0],
        s[1] + h * k[1],
        s[2] + h * k[2],
        s[3] + h * k[3],
        s[4] + h * k[4],
        s[5] + h * k[5],
    )
