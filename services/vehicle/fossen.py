"""REMUS 100 3-DOF plant (surge, sway, yaw) after Fossen, with Prestero's coefficients, and RK4.

Frames. World: x east, y north, heading psi counter-clockwise from +x (the project's frame).
Body: x forward, y to port, yaw rate r > 0 counter-clockwise. Prestero and Fossen write the
equations in a body frame with y to starboard and z down (NED); with v' = -v, r' = -r,
Y' = -Y, N' = -N the horizontal-plane equations below are unchanged, term for term (each
hydrodynamic term is odd in (v, r), and X is even), except the rudder's: with delta kept as
Prestero's delta_r (positive turns to port), its force and moment change sign. So a positive
rudder makes a positive (counter-clockwise) r here.

Model ([F] Fossen, Handbook of Marine Craft Hydrodynamics and Motion Control, 2011/2021;
[P] Prestero, MSc thesis MIT/WHOI 2001; values in common/config/fossen.py), nu_r = (u, v, r)
the velocity relative to the water, origin at the centre of buoyancy, x_g = y_g = 0:

    M nu_r' + C_RB(nu_r) nu_r + C_A(nu_r) nu_r + D(nu_r) nu_r = tau
    M = M_RB + M_A = [[m - X_udot, 0, 0], [0, m - Y_vdot, -Y_rdot], [0, -N_vdot, Izz - N_rdot]]

component by component (the surge row decouples: M is block diagonal):

    (m - X_udot) u' = X_u|u| u|u| + (m - Y_vdot) v r - Y_rdot r^2 - d_u u + T
    (m - Y_vdot) v' - Y_rdot r' = Y_v|v| v|v| + Y_r|r| r|r| + Y_uv u v + (Y_ur - m) u r
                                  - d_v v - Y_uudr u|u| delta
    -N_vdot v' + (Izz - N_rdot) r' = N_v|v| v|v| + N_r|r| r|r| + N_uv u v + N_ur u r
                                     - d_r r - N_uudr u|u| delta

- C_RB: m v r in surge, -m u r in sway;
- C_A (added-mass Coriolis and the Munk moment): -(Y_vdot v + Y_rdot r) r in surge (Prestero's
  X_vr = -Y_vdot, X_rr = -Y_rdot, derived here from the added mass), X_udot u r in sway and
  (Y_vdot - X_udot) u v + Y_rdot u r in yaw, which Prestero's combined Y_ur, N_uv, N_ur
  already contain together with body and fin lift;
- D: Prestero's quadratic cross-flow drag and axial drag X_u|u|, and Fossen's (remus100)
  low-speed linear damping d_i = M_ii / T_i exp(-fade U_r), U_r = |(u, v)|;
- tau: the propeller's net thrust T and the rudder's lift Y_uudr u|u| delta,
  N_uudr u|u| delta (u|u| rather than u^2 so that the lift reverses with the flow).

Ocean current: the hydrodynamics act on nu_r only, and the position moves with it plus the
current, eta' = R(psi) nu_r + (c_x, c_y). This is Fossen's relative-velocity formulation,
exact for an irrotational current constant in the world frame (then M_RB nu' + C_RB(nu) nu
= M_RB nu_r' + C_RB(nu_r) nu_r); for the project's shear, tides, eddies and gusts it holds
while the current varies slowly over the hull and over a second or so. A vehicle holding
u = v = 0 through the water drifts with the current.

Actuators: a first-order lag whose rate saturates smoothly (tanh), demands clamped:

    T' = Tdot_max tanh((T_dem - T) / (tau_T Tdot_max)),       T_dem in [T_min, T_max]
    delta' = rate tanh((delta_dem - delta) / (tau_d rate)),   delta_dem in [-delta_max, delta_max]

Inner autopilots (the vehicle's own low-level control), v_c = clamp(v_cmd, 0, v_max):

    T_dem = clamp(-X_u|u| v_c|v_c| + d_u(v_c) v_c + kp (v_c - u) + ki z_u)   drag feed-forward + PI
    delta_dem = clamp(delta_ss(w_cmd / u_s) + g (kp_r e_r + ki_r z_r)),       e_r = w_cmd - r
    g = (u_ref / u_s)^2 (the fin lift scales with u^2),  u_s = max(u, u_min)
    z' = e / (1 + (e / band)^2), divided by 1 + (excess / eps)^2 while the demand saturates
         in the direction of e: it integrates near the set point only, and not into a limit

The right-hand side is continuous everywhere (clamps and max, no jumps) and smooth but at the
clamps' corners, so RK4 keeps its accuracy: halving h = 0.01 s changes the state after 10 s
by < 1e-6 m (tests/test_fossen_remus.py).

delta_ss(kappa) is this model's own steady-turn rudder for the path curvature kappa = r / u:
with v = a u, r = kappa u every force scales with u|u|, and the sway-yaw balance gives a in
closed form (a quadratic in |a|), then delta from the sway equation (the low-speed linear
damping is neglected in it). Nothing bounds r by v / R_min: the turning radius comes out of
the hydrodynamics and the rudder limit (about 6 m at full rudder, at any speed).
"""

from __future__ import annotations

import math
from collections.abc import Callable

from common.config.fossen import FossenConfig

# (x, y, psi, u, v, r, thrust_n, rudder_rad, z_u, z_r): world position (m) and heading (rad,
# not wrapped), velocity through the water in the body frame (m/s, m/s, rad/s), the actual
# propeller thrust (N) and rudder angle (rad), the speed and yaw-rate autopilots' integrators
FossenState = tuple[float, ...]
# (s, t_dem, d_dem, cx, cy, dz_u, dz_r) -> s' for saturated demands (_bind_rhs)
_Rhs = Callable[[FossenState, float, float, float, float, float, float], FossenState]
# (s, vc, ff, w_cmd, cx, cy) -> s' under the autopilots (_bind_closed_loop)
_ClosedLoop = Callable[[FossenState, float, float, float, float, float], FossenState]
# current(x, y, t) -> the water's velocity (cx, cy) (world frame, m/s)
_Current = Callable[[float, float, float], tuple[float, float]]
# (s, h, t0, v_cmd, w_cmd, current) -> the state h later (_bind_step)
_Step = Callable[[FossenState, float, float, float, float, _Current], FossenState]


class FossenPlant:
    """The REMUS 100 3-DOF plant: derivatives under the autopilots or open loop, and RK4."""

    def __init__(self, cfg: FossenConfig, *, v_max_mps: float) -> None:
        if not (math.isfinite(v_max_mps) and v_max_mps > 0.0):
            raise ValueError(f"v_max_mps: {v_max_mps!r} is invalid, expected a value > 0")
        self.cfg = cfg
        self.v_max_mps = v_max_mps
        m = cfg.mass_kg
        m11 = m - cfg.x_udot_kg
        m22 = m - cfg.y_vdot_kg
        m66 = cfg.izz_kgm2 - cfg.n_rdot_kgm2
        det = m22 * m66 - cfg.y_rdot_kgm * cfg.n_vdot_kgm
        # in the project's frame the rudder's force and moment change sign (module docstring)
        y_d = -cfg.y_uudr_kgpm
        n_d = -cfg.n_uudr_kg
        # steady-turn feed-forward: N - q Y eliminates delta; A a|a| + B a = -(C2 k|k| + C1 k)
        q = n_d / y_d
        self._ff = (
            -(cfg.n_vv_kg - q * cfg.y_vv_kgpm),  # -A >= 0
            -(cfg.n_uv_kg - q * cfg.y_uv_kgpm),  # -B > 0
            cfg.n_rr_kgm2 - q * cfg.y_rr_kgm,  # C2
            cfg.n_ur_kgm - q * (cfg.y_ur_kg - m),  # C1
            cfg.y_vv_kgpm,
            cfg.y_rr_kgm,
            cfg.y_uv_kgpm,
            cfg.y_ur_kg - m,
            y_d,
        )
        # straight-line resistance: -X_u|u| u|u| + d_u exp(-fade |u|) u
        self._drag = (-cfg.x_uu_kgpm, m11 / cfg.surge_time_constant_s, cfg.linear_damping_fade_spm)
        self._ap = (
            cfg.speed_kp_npmps,
            cfg.speed_ki_npm,
            cfg.speed_int_band_mps,
            0.05 * (cfg.thrust_max_n - cfg.thrust_min_n),
            cfg.yaw_rate_kp_s,
            cfg.yaw_rate_ki,
            cfg.yaw_rate_int_band_rps,
            0.05 * cfg.rudder_max_rad,
            cfg.autopilot_u_ref_mps,
            cfg.autopilot_u_min_mps,
        )
        self._sat = (cfg.thrust_min_n, cfg.thrust_max_n, cfg.rudder_max_rad)
        self._p = (
            1.0 / m11,
            m22,  # m - Y_vdot: C_RB's m plus C_A's X_vr = -Y_vdot
            -cfg.y_rdot_kgm,  # X_rr = -Y_rdot
            cfg.x_uu_kgpm,
            m11 / cfg.surge_time_constant_s,
            m22 / cfg.sway_time_constant_s,
            m66 / cfg.yaw_time_constant_s,
            cfg.linear_damping_fade_spm,
            cfg.y_vv_kgpm,
            cfg.y_rr_kgm,
            cfg.y_uv_kgpm,
            cfg.y_ur_kg - m,
            y_d,
            cfg.n_vv_kg,
            cfg.n_rr_kgm2,
            cfg.n_uv_kg,
            cfg.n_ur_kgm,
            n_d,
            m66 / det,  # (M^-1)_vv
            cfg.y_rdot_kgm / det,  # (M^-1)_vr
            cfg.n_vdot_kgm / det,  # (M^-1)_rv
            m22 / det,  # (M^-1)_rr
            cfg.thrust_min_n,
            cfg.thrust_max_n,
            1.0 / cfg.thrust_time_constant_s,
            cfg.thrust_rate_max_nps,
            cfg.rudder_max_rad,
            1.0 / cfg.rudder_time_constant_s,
            cfg.rudder_rate_max_rps,
        )
        # the right-hand side with these constants bound once (~25k calls an ocean mission)
        self._rhs = _bind_rhs(self._p)
        self._steady_rudder = _bind_steady_rudder(self._ff)
        self._closed_loop = _bind_closed_loop(self._ap, self._sat, self._steady_rudder, self._rhs)
        self._step = _bind_step(self._closed_loop, v_max_mps, self.drag_n)

    def initial(
        self, x: float, y: float, psi: float, u: float = 0.0, v: float = 0.0, r: float = 0.0
    ) -> FossenState:
        """A state at pose (x, y, psi) moving at nu_r = (u, v, r), trimmed: the thrust balances
        the drag at u, the rudder holds the steady turn of curvature r / u (zero at rest),
        integrators at zero."""
        cfg = self.cfg
        u_s = max(u, cfg.autopilot_u_min_mps)
        thrust = self.drag_n(u) if u > 0.0 else 0.0
        thrust = min(max(thrust, cfg.thrust_min_n), cfg.thrust_max_n)
        rudder = self.steady_rudder_rad(r / u_s) if u > 0.0 else 0.0
        rudder = min(max(rudder, -cfg.rudder_max_rad), cfg.rudder_max_rad)
        return (x, y, psi, u, v, r, thrust, rudder, 0.0, 0.0)

    def drag_n(self, u: float) -> float:
        """Straight-line surge resistance at u: -X_u|u| u|u| + d_u(u) u (the speed feed-forward)."""
        c2, c1, fade = self._drag
        return c2 * u * abs(u) + c1 * math.exp(-fade * abs(u)) * u

    def steady_rudder_rad(self, kappa: float) -> float:
        """Rudder angle of this model's steady turn of path curvature kappa = r / u (1/m),
        u > 0, low-speed linear damping neglected (unsaturated: may exceed rudder_max_rad)."""
        return self._steady_rudder(kappa)

    def derivatives(
        self, s: FossenState, v_cmd: float, w_cmd: float, cx: float, cy: float
    ) -> FossenState:
        """Right-hand side under a commanded surge speed through the water v_cmd (m/s) and yaw
        rate w_cmd (rad/s), in a current (cx, cy) (world frame, m/s) at the vehicle."""
        vc = min(max(v_cmd, 0.0), self.v_max_mps)
        return self._closed_loop(s, vc, self.drag_n(vc), w_cmd, cx, cy)

    def derivatives_open_loop(
        self, s: FossenState, thrust_n: float, rudder_rad: float, cx: float, cy: float
    ) -> FossenState:
        """Right-hand side with the actuators commanded directly (autopilots bypassed, their
        integrators frozen); the demands still saturate and pass the actuator dynamics."""
        t_min, t_max, d_max = self._sat
        t_dem = min(max(thrust_n, t_min), t_max)
        d_dem = min(max(rudder_rad, -d_max), d_max)
        return self._rhs(s, t_dem, d_dem, cx, cy, 0.0, 0.0)

    def step(
        self,
        s: FossenState,
        h: float,
        t0: float,
        v_cmd: float,
        w_cmd: float,
        current: _Current,
    ) -> FossenState:
        """One classical RK4 step of length h from time t0 under a held (v_cmd, w_cmd);
        current(x, y, t) is evaluated at each stage's position and time."""
        return self._step(s, h, t0, v_cmd, w_cmd, current)

    @staticmethod
    def pose(s: FossenState) -> tuple[float, float, float, float, float, float]:
        """(x, y, psi, u, v, r) of a state."""
        return s[0], s[1], s[2], s[3], s[4], s[5]


def _bind_step(f: _ClosedLoop, v_max: float, drag_n: Callable[[float], float]) -> _Step:
    """FossenPlant.step over the bound right-hand side f: the speed command's bound and drag
    feed-forward formed once a step, the stage points and the sum written out component by
    component (as s + h k and a sum over zip form them, tuple by tuple: the same floats,
    without the loops), min(max(v_cmd, 0.0), v_max) as the conditionals it is."""

    def step(
        s: FossenState, h: float, t0: float, v_cmd: float, w_cmd: float, current: _Current
    ) -> FossenState:
        vc = 0.0 if 0.0 > v_cmd else v_cmd
        vc = v_max if v_max < vc else vc
        ff = drag_n(vc)  # the speed autopilot's feed-forward, held over the step
        hh = 0.5 * h
        # s0..s9 the state (x, y, psi, u, v, r, thrust, rudder, z_u, z_r); a, b, c, d the
        # components of k1..k4 in that order
        s0, s1, s2, s3, s4, s5, s6, s7, s8, s9 = s
        a0, a1, a2, a3, a4, a5, a6, a7, a8, a9 = f(s, vc, ff, w_cmd, *current(s0, s1, t0))
        x, y = s0 + hh * a0, s1 + hh * a1
        q = (x, y, s2 + hh * a2, s3 + hh * a3, s4 + hh * a4, s5 + hh * a5, s6 + hh * a6,
             s7 + hh * a7, s8 + hh * a8, s9 + hh * a9)  # fmt: skip
        b0, b1, b2, b3, b4, b5, b6, b7, b8, b9 = f(q, vc, ff, w_cmd, *current(x, y, t0 + hh))
        x, y = s0 + hh * b0, s1 + hh * b1
        q = (x, y, s2 + hh * b2, s3 + hh * b3, s4 + hh * b4, s5 + hh * b5, s6 + hh * b6,
             s7 + hh * b7, s8 + hh * b8, s9 + hh * b9)  # fmt: skip
        c0, c1, c2, c3, c4, c5, c6, c7, c8, c9 = f(q, vc, ff, w_cmd, *current(x, y, t0 + hh))
        x, y = s0 + h * c0, s1 + h * c1
        q = (x, y, s2 + h * c2, s3 + h * c3, s4 + h * c4, s5 + h * c5, s6 + h * c6,
             s7 + h * c7, s8 + h * c8, s9 + h * c9)  # fmt: skip
        d0, d1, d2, d3, d4, d5, d6, d7, d8, d9 = f(q, vc, ff, w_cmd, *current(x, y, t0 + h))
        h6 = h / 6.0
        # s + h/6 (k1 + 2 k2 + 2 k3 + k4)
        return (
            s0 + h6 * (a0 + 2.0 * b0 + 2.0 * c0 + d0),
            s1 + h6 * (a1 + 2.0 * b1 + 2.0 * c1 + d1),
            s2 + h6 * (a2 + 2.0 * b2 + 2.0 * c2 + d2),
            s3 + h6 * (a3 + 2.0 * b3 + 2.0 * c3 + d3),
            s4 + h6 * (a4 + 2.0 * b4 + 2.0 * c4 + d4),
            s5 + h6 * (a5 + 2.0 * b5 + 2.0 * c5 + d5),
            s6 + h6 * (a6 + 2.0 * b6 + 2.0 * c6 + d6),
            s7 + h6 * (a7 + 2.0 * b7 + 2.0 * c7 + d7),
            s8 + h6 * (a8 + 2.0 * b8 + 2.0 * c8 + d8),
            s9 + h6 * (a9 + 2.0 * b9 + 2.0 * c9 + d9),
        )

    return step


def _bind_steady_rudder(ff: tuple[float, ...]) -> Callable[[float], float]:
    """FossenPlant.steady_rudder_rad with its feed-forward constants ff bound once."""
    na, nb, c2, c1, y_vv, y_rr, y_uv, y_ur_m, y_d = ff
    sqrt = math.sqrt

    def steady_rudder(kappa: float) -> float:
        k = -(c2 * kappa * abs(kappa) + c1 * kappa)  # = A a|a| + B a, decreasing in a
        kk = abs(k)
        # |a| solves na a^2 + nb a = |k| (rationalised root: exact for na = 0 too)
        a_abs = 2.0 * kk / (nb + sqrt(nb * nb + 4.0 * na * kk))
        a = -a_abs if k > 0.0 else a_abs
        # sway balance: Y_vv a|a| + Y_rr k|k| + Y_uv a + (Y_ur - m) k + Y_d delta = 0
        return -(y_vv * a * abs(a) + y_rr * kappa * abs(kappa) + y_uv * a + y_ur_m * kappa) / y_d

    return steady_rudder


def _bind_closed_loop(
    ap: tuple[float, ...],
    sat: tuple[float, float, float],
    steady_rudder: Callable[[float], float],
    rhs: _Rhs,
) -> _ClosedLoop:
    """`derivatives` for the speed command vc already bounded and its drag feed-forward ff
    (both held over an RK4 step: `step` forms them once), the autopilots' gains ap and the
    saturations sat bound once. min(max(x, lo), hi) is written out (max(a, b) is b if b > a
    else a, min(a, b) b if b < a else a: the same floats)."""
    kp_u, ki_u, band_u, eps_u, kp_r, ki_r, band_r, eps_r, u_ref, u_min = ap
    t_min, t_max, d_max = sat
    d_min = -d_max  # negation is exact: the same float as -d_max formed at each call

    def closed_loop(
        s: FossenState, vc: float, ff: float, w_cmd: float, cx: float, cy: float
    ) -> FossenState:
        u = s[3]
        # speed autopilot: drag feed-forward + PI
        e_u = vc - u
        t_raw = ff + kp_u * e_u + ki_u * s[8]
        t_dem = t_min if t_min > t_raw else t_raw
        t_dem = t_max if t_max < t_dem else t_dem
        # yaw-rate autopilot: steady-turn feed-forward + PI scheduled with the fin lift ~ u^2
        u_s = u_min if u_min > u else u
        g = u_ref / u_s
        g *= g
        e_r = w_cmd - s[5]
        d_raw = steady_rudder(w_cmd / u_s) + g * (kp_r * e_r + ki_r * s[9])
        d_dem = d_min if d_min > d_raw else d_raw
        d_dem = d_max if d_max < d_dem else d_dem
        dz_u = _integrand(e_u, band_u, t_raw - t_dem, eps_u)
        dz_r = _integrand(e_r, band_r, d_raw - d_dem, eps_r)
        return rhs(s, t_dem, d_dem, cx, cy, dz_u, dz_r)

    return closed_loop


def _bind_rhs(p: tuple[float, ...]) -> _Rhs:
    """Kinematics, rigid body + hydrodynamics and actuators for saturated demands (t_dem,
    d_dem), the integrators' rates (dz_u, dz_r) passed through, FossenPlant._p bound once."""
    (
        inv_m11, x_vr, x_rr, x_uu, du0, dv0, dr0, fade,
        y_vv, y_rr, y_uv, y_ur_m, y_d,
        n_vv, n_rr, n_uv, n_ur, n_d,
        mi_vv, mi_vr, mi_rv, mi_rr,
        _t_min, _t_max, inv_tau_t, t_rate, d_max, inv_tau_d, d_rate,
    ) = p  # fmt: skip
    cos, sin, exp, sqrt, tanh = math.cos, math.sin, math.exp, math.sqrt, math.tanh

    def rhs(
        s: FossenState, t_dem: float, d_dem: float, cx: float, cy: float, dz_u: float, dz_r: float
    ) -> FossenState:
        _, _, psi, u, v, r, thrust, rudder, _, _ = s
        c = cos(psi)
        sn = sin(psi)
        au = abs(u)
        av = abs(v)
        ar = abs(r)
        lin = exp(-fade * sqrt(u * u + v * v))
        # the actual rudder, held to its limit (an RK4 stage may overshoot it slightly)
        dl = d_max if rudder > d_max else -d_max if rudder < -d_max else rudder
        fin = u * au * dl
        # surge: (m - X_udot) u' = X_u|u| u|u| + (m - Y_vdot) v r - Y_rdot r^2 - d_u u + T
        du = (x_uu * u * au + x_vr * v * r + x_rr * r * r - du0 * lin * u + thrust) * inv_m11
        # sway and yaw forces, then M^-1 of the coupled 2x2 block
        fy = y_vv * v * av + y_rr * r * ar + y_uv * u * v + y_ur_m * u * r - dv0 * lin * v
        fy += y_d * fin
        fn = n_vv * v * av + n_rr * r * ar + n_uv * u * v + n_ur * u * r - dr0 * lin * r
        fn += n_d * fin
        # actuators: first-order lags whose rates saturate smoothly (no corner for RK4)
        dt = t_rate * tanh((t_dem - thrust) * inv_tau_t / t_rate)
        dd = d_rate * tanh((d_dem - rudder) * inv_tau_d / d_rate)
        return (
            u * c - v * sn + cx,  # eta' = R(psi) nu_r + current
            u * sn + v * c + cy,
            r,
            du,
            mi_vv * fy + mi_vr * fn,
            mi_rv * fy + mi_rr * fn,
            dt,
            dd,
            dz_u,
            dz_r,
        )

    return rhs


def _integrand(e: float, band: float, excess: float, eps: float) -> float:
    """An autopilot integrator's rate: e weighted by 1 / (1 + (e / band)^2), so that it
    integrates near the set point only (large transients do not wind it up), and by
    1 / (1 + (excess / eps)^2) while the demand saturates in the direction of e (conditional
    integration). Smooth (C1) in e and excess, so RK4 keeps its order."""
    w = e / band
    rate = e / (1.0 + w * w)
    if e * excess > 0.0:
        x = excess / eps
        return rate / (1.0 + x * x)
    return rate
