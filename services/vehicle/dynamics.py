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
from collections.abc import Callable
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


# (s, h, v_cmd, w_cmd, t, current) -> the state h seconds later (make_rk4_step)
Rk4Step = Callable[[State, float, float, float, float, CurrentFn | None], State]


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
    away). A plant stepping often binds p once instead (`make_rk4_step`).
    """
    return make_rk4_step(p)(s, h, v_cmd, w_cmd, t, current)


RatesFn = Callable[[float, float, float, float, float, float], tuple[float, float, float]]


def _bind_rates(p: PlantParams) -> tuple[Callable[[float], float], RatesFn]:
    """drag_n(v) and derivatives' (dv, dw, dz) at (v, w, z) under (v_cmd, w_cmd) with the
    drag feed-forward ff, p's fields read once: make_rk4_step's stages."""
    half_rho_s, length_m, nu_m2ps = p.half_rho_s, p.length_m, p.nu_m2ps
    delta_cf, c_pv, mass_eff_kg = p.delta_cf, p.c_pv, p.mass_eff_kg
    t_min, t_max, kp, ki, int_band = p.thrust_min_n, p.thrust_max_n, p.kp, p.ki, p.int_band
    accel_max, yaw_tau_s, yaw_accel_max = p.accel_max, p.yaw_tau_s, p.yaw_accel_max
    r_min = p.r_min
    exp, log10 = math.exp, math.log10

    def drag(v: float) -> float:
        # drag_n and friction_coefficient
        re = abs(v) * length_m / nu_m2ps
        if re < RE_MIN:  # max(re, RE_MIN): RE_MIN when equal too, the same float
            re = RE_MIN
        cf = 0.075 / (log10(re) - 2.0) ** 2
        return half_rho_s * v * abs(v) * (cf + delta_cf + c_pv)

    def rates(
        v: float, w: float, z: float, v_cmd: float, w_cmd: float, ff: float
    ) -> tuple[float, float, float]:
        # derivatives' dv, dw and dz (thrust_n's): the clamps are common.scalar.clamp's
        # expression written out
        e = v_cmd - v
        t_raw = ff + kp * e + ki * z
        t = t_min if t_raw < t_min else t_max if t_raw > t_max else t_raw
        x = e / int_band
        dz = exp(-x * x) * (e + (t - t_raw) / kp)
        dv = (t - drag(v)) / mass_eff_kg
        dv = -accel_max if dv < -accel_max else accel_max if dv > accel_max else dv
        w_room = abs(v) / r_min
        wc = -w_room if w_cmd < -w_room else w_room if w_cmd > w_room else w_cmd
        dw = (wc - w) / yaw_tau_s
        dw = -yaw_accel_max if dw < -yaw_accel_max else yaw_accel_max if dw > yaw_accel_max else dw
        return dv, dw, dz

    return drag, rates


def make_rk4_step(p: PlantParams) -> Rk4Step:
    """rk4_step with p bound: step(s, h, v_cmd, w_cmd, t, current) -> the state h later.

    The vehicle's hot loop (~8000 steps a mission): `derivatives`, `thrust_n`, `drag_n` and
    `clamp` are written out here with p's fields read once, in the same expressions and
    operation order, so the floats are theirs bit for bit (tests/test_vehicle_dynamics.py
    holds the two equal); the drag feed-forward of the last v_cmd is kept (a command is
    held over many steps)."""
    v_max, w_min, w_max, r_min = p.v_max, p.w_min, p.w_max, p.r_min
    cos, sin = math.cos, math.sin
    drag, rates = _bind_rates(p)
    ff_of: list[float] = [math.nan, 0.0]  # (v_cmd, drag_n(v_cmd)) of the last step

    def slope(
        s: State, t: float, v_cmd: float, w_cmd: float, ff: float, current: CurrentFn | None
    ) -> State:
        # derivatives' at s and t, with the water's velocity added to the kinematics
        x, y, th, v, w, z = s
        cx, cy = (0.0, 0.0) if current is None else current(x, y, t)
        dv, dw, dz = rates(v, w, z, v_cmd, w_cmd, ff)
        return v * cos(th) + cx, v * sin(th) + cy, w, dv, dw, dz

    def ahead(s: State, a: float, k: State) -> State:
        # s + a k: the point a stage is evaluated at
        x, y, th, v, w, z = s
        kx, ky, kt, kv, kw, kz = k
        return x + a * kx, y + a * ky, th + a * kt, v + a * kv, w + a * kw, z + a * kz

    def step(
        s: State, h: float, v_cmd: float, w_cmd: float, t: float, current: CurrentFn | None
    ) -> State:
        if ff_of[0] != v_cmd or v_cmd == 0.0:  # equal and nonzero: the same float, bit for bit
            ff_of[0], ff_of[1] = v_cmd, drag(v_cmd)
        ff = ff_of[1]
        hh = 0.5 * h
        # classical RK4: k1 at s, k2 and k3 at s + h/2 k (the stage before), k4 at s + h k3
        k1 = slope(s, t, v_cmd, w_cmd, ff, current)
        k2 = slope(ahead(s, hh, k1), t + hh, v_cmd, w_cmd, ff, current)
        k3 = slope(ahead(s, hh, k2), t + hh, v_cmd, w_cmd, ff, current)
        k4 = slope(ahead(s, h, k3), t + h, v_cmd, w_cmd, ff, current)
        h6 = h / 6.0
        # s + h/6 (k1 + 2 k2 + 2 k3 + k4), component by component
        x0, y0, th0, v0, w0, z0 = s
        k1x, k1y, _, k1v, k1w, k1z = k1
        k2x, k2y, k2t, k2v, k2w, k2z = k2
        k3x, k3y, k3t, k3v, k3w, k3z = k3
        k4x, k4y, k4t, k4v, k4w, k4z = k4
        v = v0 + h6 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v)
        w = w0 + h6 * (k1w + 2.0 * k2w + 2.0 * k3w + k4w)
        v = 0.0 if v < 0.0 else v_max if v > v_max else v
        w_room = v / r_min
        lo = -w_room if -w_room > w_min else w_min  # max(w_min, -w_room), written out
        hi = w_room if w_room < w_max else w_max  # min(w_max, w_room)
        return (
            x0 + h6 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x),
            y0 + h6 * (k1y + 2.0 * k2y + 2.0 * k3y + k4y),
            th0 + h6 * (w0 + 2.0 * k2t + 2.0 * k3t + k4t),
            v,
            lo if w < lo else hi if w > hi else w,
            z0 + h6 * (k1z + 2.0 * k2z + 2.0 * k3z + k4z),
        )

    return step
