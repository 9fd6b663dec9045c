"""Where moving obstacles will be when the vehicle gets there: discs for the search grid.

Eq. (12)-(13) compare the vehicle with alpha_k(t) at the time it passes. The grid search
cannot know that time exactly, so it blocks the obstacle's swept positions over a window
around an estimate of it; the refinement and the final check then use the exact time
t = s / v_ref along the curve. If the check still finds a conflict, the planner re-blocks
each obstacle around the time the failed curve actually passed it (`passing_discs`).
"""

from __future__ import annotations

import math

import numpy as np

from common.config.planner import PlannerConfig
from common.world import ObstacleState
from common.world.geometry import FloatArray
from services.planner.geometry.nurbs_curve import NurbsCurve
from services.planner.result import Pose2D


def intercept_time(
    obs: ObstacleState, start: Pose2D, v_ref: float, accel_horizon_s: float, t_max: float
) -> float:
    """Earliest t with |alpha_k(t) - start| = v_ref t: a straight dash reaching the obstacle."""
    t = 0.0
    for _ in range(8):  # fixed point; converges while the obstacle is slower than the vehicle
        p = obs.centre_at(float(t), accel_horizon_s)
        t_new = min(float(np.hypot(p[0] - start.x, p[1] - start.y)) / v_ref, t_max)
        if abs(t_new - t) < 1e-3:
            return t_new
        t = t_new
    return t


def swept_discs(obs: ObstacleState, t_mid: float, cfg: PlannerConfig) -> FloatArray:
    """Discs (n, 3: x, y, r_k) covering alpha_k(t) for t in t_mid +- moving_window_s (t >= 0)."""
    t0, t1 = max(0.0, t_mid - cfg.moving_window_s), t_mid + cfg.moving_window_s
    speed = math.hypot(obs.vx, obs.vy) + math.hypot(obs.ax, obs.ay) * min(t1, cfg.accel_horizon_s)
    step = max(0.5 * max(obs.radius, cfg.resolution_m), 1e-3)  # metres between disc centres
    n = min(40, max(2, math.ceil((t1 - t0) * speed / step) + 1))
    pos = obs.centre_at(np.linspace(t0, t1, n), cfg.accel_horizon_s)
    return np.column_stack([pos, np.full(len(pos), obs.radius)])


def predicted_discs(
    moving: tuple[ObstacleState, ...], start: Pose2D, v_ref: float, t_max: float, cfg: PlannerConfig
) -> FloatArray:
    """Swept discs (k, 3) of every moving obstacle around its straight-line intercept time."""
    out = [np.zeros((0, 3))]
    for o in moving:
        out.append(swept_discs(o, intercept_time(o, start, v_ref, cfg.accel_horizon_s, t_max), cfg))
    return np.concatenate(out)


def passing_discs(
    curve: NurbsCurve, moving: tuple[ObstacleState, ...], v_ref: float, cfg: PlannerConfig
) -> FloatArray:
    """Swept discs (k, 3) around the time the given curve comes closest to each moving obstacle."""
    u = np.linspace(curve.u_min, curve.u_max, 800)
    pts = curve.evaluate(u, n_ders=0)[0]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    t = s / v_ref
    out = [np.zeros((0, 3))]
    for o in moving:
        gap = np.hypot(*(pts - o.centre_at(t, cfg.accel_horizon_s)).T)
        out.append(swept_discs(o, float(t[int(np.argmin(gap))]), cfg))
    return np.concatenate(out)
