"""The full replan pipeline: cost map, graph search, pruning, NURBS fit, refinement, check.

`plan_path(request, config)` is a pure function: no clock unless one is handed in (only to
fill the timing breakdown), no randomness. A walled-off or unsafe goal, or a curve that
cannot be made to satisfy eq. (12)-(13) and (20), yields status NO_PATH with a reason,
never a colliding path.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from common.config.planner import PlannerConfig
from services.planner.check import CurveCheck, check_curve
from services.planner.costmap import CostMap, build_costmap
from services.planner.fit import FitProblem, initial_curve
from services.planner.geometry import (
    Area,
    Circle,
    FloatArray,
    MovingCircle,
    Obstacles,
    Pose2D,
    StaticField,
    moving_distance,
)
from services.planner.nurbs import Nurbs
from services.planner.refine import RefineWeights, refine
from services.planner.search import prune_path, shortest_path

PlanStatus = Literal["OK", "NO_PATH"]


@dataclass(frozen=True, kw_only=True)
class PlanRequest:
    """One planning problem. Moving obstacles are given by their state at plan time t = 0."""

    start: Pose2D
    goal: Pose2D
    area: Area = field(default_factory=Area)
    obstacles: Obstacles = field(default_factory=Obstacles)
    vehicle_radius_m: float = 0.1  # REMUS-100: 0.19 m diameter
    r_min_m: float = 2.0  # minimum turning radius R_min (eq. (19)-(20))
    v_ref_mps: float = 1.5  # cruise speed: converts arc length to passing time, eq. (13)
    fix_goal_heading: bool = True  # eq. (10): also impose theta_f at the goal

    def __post_init__(self) -> None:
        for name in ("vehicle_radius_m", "r_min_m", "v_ref_mps"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: {v!r} is invalid, expected a finite value > 0")


@dataclass(frozen=True, kw_only=True)
class PlanTiming:
    """Seconds spent per stage (all zero when no clock was handed to plan_path)."""

    costmap_s: float = 0.0
    search_s: float = 0.0
    fit_s: float = 0.0  # initial fit + refinement rounds
    check_s: float = 0.0
    total_s: float = 0.0


@dataclass(frozen=True, kw_only=True, eq=False)
class PlanResult:
    """A planned NURBS path (status OK) or NO_PATH with its reason."""

    status: PlanStatus
    reason: str
    degree: int = 0
    control_points: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))
    weights: FloatArray = field(default_factory=lambda: np.zeros(0))
    knots: FloatArray = field(default_factory=lambda: np.zeros(0))
    grid_path: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))  # pruned waypoints
    length_m: float = 0.0  # eq. (16)/(18) length of the curve
    f_l: float = 0.0  # L / straight-line start-goal distance
    max_curvature: float = 0.0  # 1/m, dense samples; < 1/R_min when OK (eq. (20))
    min_clearance_m: float = 0.0  # hull-to-obstacle-surface minimum; >= rho0 when OK
    turn_penalty: float = 0.0  # eq. (19) f_R of the final curve
    rounds: int = 0  # refinement rounds used
    timing: PlanTiming = field(default_factory=PlanTiming)

    @property
    def ok(self) -> bool:
        return self.status == "OK"

    def curve(self) -> Nurbs:
        if not self.ok:
            raise ValueError(f"no curve: {self.reason}")
        return Nurbs(self.degree, self.control_points, self.weights, self.knots)


def intercept_time(
    obs: MovingCircle, start: Pose2D, v_ref: float, horizon: float, t_max: float
) -> float:
    """Time when a vehicle leaving `start` at v_ref could first reach the obstacle (fixed point)."""
    t = 0.0
    for _ in range(8):
        p = obs.positions(np.array([t]), horizon)[0]
        t_new = min(float(np.hypot(p[0] - start.x, p[1] - start.y)) / v_ref, t_max)
        if abs(t_new - t) < 1e-3:
            return t_new
        t = t_new
    return t


def predicted_discs(req: PlanRequest, cfg: PlannerConfig) -> tuple[Circle, ...]:
    """Discs covering each moving obstacle over +-moving_window_s around its intercept time.

    eq. (12)-(13) need alpha_k(t) at the time the vehicle passes; the grid cannot know that
    time exactly, so it blocks the swept positions near the intercept time; the refinement
    and the final check then use the exact time t = s / v_ref along the curve.
    """
    a = req.area
    t_max = math.hypot(a.x_max - a.x_min, a.y_max - a.y_min) * 2.0 / req.v_ref_mps
    out: list[Circle] = []
    for o in req.obstacles.moving:
        t_hit = intercept_time(o, req.start, req.v_ref_mps, cfg.accel_horizon_s, t_max)
        t0, t1 = max(0.0, t_hit - cfg.moving_window_s), t_hit + cfg.moving_window_s
        speed = math.hypot(o.vx, o.vy) + math.hypot(o.ax, o.ay) * min(t1, cfg.accel_horizon_s)
        step = max(0.5 * max(o.radius, cfg.resolution_m), 1e-3)  # metres between discs
        n = min(40, max(2, math.ceil((t1 - t0) * speed / step) + 1))
        for p in o.positions(np.linspace(t0, t1, n), cfg.accel_horizon_s):
            out.append(Circle(x=float(p[0]), y=float(p[1]), radius=o.radius))
    return tuple(out)


def _no_path(reason: str, timing: PlanTiming, grid: FloatArray | None = None) -> PlanResult:
    return PlanResult(
        status="NO_PATH",
        reason=reason,
        grid_path=np.zeros((0, 2)) if grid is None else grid,
        timing=timing,
    )


def _unblock_start_goal(
    cmap: CostMap, start: Pose2D, goal: Pose2D, r: float, escape_m: float
) -> CostMap:
    """Let the search leave a start that lies inside the safety margin (but not in contact).

    Cells within escape_m of the start whose centre keeps the hull off every obstacle
    become passable (at the capped cost, so the path leaves the margin as soon as it can);
    the start and goal cells themselves are always passable (their exact clearance is checked).
    """
    blocked = cmap.blocked.copy()
    xs = cmap.area.x_min + (np.arange(cmap.nx) + 0.5) * cmap.resolution_m
    ys = cmap.area.y_min + (np.arange(cmap.ny) + 0.5) * cmap.resolution_m
    near = np.hypot(xs[None, :] - start.x, ys[:, None] - start.y) <= escape_m
    blocked &= ~(near & (cmap.clearance > r))
    for p in (start, goal):
        ix, iy = cmap.cell_of(p.x, p.y)
        blocked[iy, ix] = False
    return dataclasses.replace(cmap, blocked=blocked)


def plan_path(
    req: PlanRequest, cfg: PlannerConfig, clock: Callable[[], float] | None = None
) -> PlanResult:
    """Plan a NURBS path from req.start to req.goal; see the module docstring."""
    now = clock if clock is not None else (lambda: 0.0)
    t_begin = now()
    marks: dict[str, float] = {}

    def timing() -> PlanTiming:
        return PlanTiming(total_s=now() - t_begin, **marks)

    r, area, obs = req.vehicle_radius_m, req.area, req.obstacles
    d_req = r + cfg.rho0_m  # eq. (12)-(13): centre-to-surface distance r + rho0 (r_k in geometry)
    s_xy = np.array([req.start.x, req.start.y])
    g_xy = np.array([req.goal.x, req.goal.y])
    if not area.contains(req.start.x, req.start.y, r):
        return _no_path("start is outside the area", timing())
    if not area.contains(req.goal.x, req.goal.y, r):
        return _no_path("goal is outside the area", timing())
    d_min = float(np.hypot(*(g_xy - s_xy)))
    if d_min < 1e-6:
        return _no_path("start is at the goal: nothing to plan", timing())
    static = StaticField.build(obs.circles, obs.polygons)
    d_goal = float(static.distance(g_xy)[0][0])
    if d_goal < d_req:
        return _no_path(
            f"goal lies within the safety distance of a static obstacle "
            f"(hull clearance {d_goal - r:.2f} m < rho0 = {cfg.rho0_m:.2f} m)",
            timing(),
        )
    d_start = min(
        float(static.distance(s_xy)[0][0]),
        float(moving_distance(obs.moving, s_xy, np.zeros(1), cfg.accel_horizon_s)[0][0]),
    )
    if d_start <= r:
        return _no_path("start is in contact with an obstacle", timing())

    t0 = now()
    cmap = build_costmap(area, static, predicted_discs(req, cfg), r, cfg)
    cmap = _unblock_start_goal(cmap, req.start, req.goal, r, cfg.escape_len_m)
    marks["costmap_s"] = now() - t0

    t0 = now()
    sx, sy = cmap.cell_of(req.start.x, req.start.y)
    gx, gy = cmap.cell_of(req.goal.x, req.goal.y)
    path = shortest_path(cmap, sy * cmap.nx + sx, gy * cmap.nx + gx, cfg.connectivity, cfg.search)
    if path is None:
        marks["search_s"] = now() - t0
        return _no_path(
            "goal unreachable: obstacles (inflated by r + rho0) wall it off from the start "
            f"on the {cfg.resolution_m:g} m grid",
            timing(),
        )
    waypoints = prune_path(cmap, path, s_xy, g_xy)
    marks["search_s"] = now() - t0

    prob = FitProblem(
        start=req.start,
        goal=req.goal,
        fix_goal_heading=req.fix_goal_heading,
        area=area,
        static=static,
        moving=obs.moving,
        vehicle_radius_m=r,
        r_min_m=req.r_min_m,
        v_ref_mps=req.v_ref_mps,
        d_req_m=d_req,
        escape_len_m=cfg.escape_len_m,
        start_inside=d_start < d_req,
        accel_horizon_s=cfg.accel_horizon_s,
        grid=cmap,
    )
    fit_s = check_s = 0.0
    spacing = cfg.ctrl_spacing_m
    wts = RefineWeights(
        c_d=cfg.penalty_clearance,
        c_k=cfg.penalty_curvature,
        clear_margin_m=cfg.clearance_margin_m,
        k_target=cfg.curvature_margin / req.r_min_m,
    )
    t0 = now()
    curve = initial_curve(prob, waypoints, spacing, cfg.nurbs_degree)
    chk: CurveCheck | None = None
    for rnd in range(cfg.refine_rounds):
        if rnd >= 2:  # fallback: more control points, seeded from the last refined curve
            spacing *= 0.5
            curve = initial_curve(prob, _resample(curve, spacing), spacing, cfg.nurbs_degree)
        curve = refine(
            prob,
            curve,
            wts,
            per_span=cfg.samples_per_span,
            max_iter=cfg.refine_max_iter,
            method=cfg.refine_method,
        )
        t1 = now()
        fit_s += t1 - t0
        chk = check_curve(curve, prob, cfg.n_samples_check)
        t0 = now()
        check_s += t0 - t1
        if chk.ok:
            marks.update(fit_s=fit_s, check_s=check_s)
            return PlanResult(
                status="OK",
                reason="",
                degree=curve.degree,
                control_points=curve.ctrl,
                weights=curve.weights,
                knots=curve.knots,
                grid_path=waypoints,
                length_m=chk.length_m,
                f_l=chk.length_m / d_min,
                max_curvature=chk.max_curvature,
                min_clearance_m=chk.min_clearance_m,
                turn_penalty=chk.turn_penalty,
                rounds=rnd + 1,
                timing=timing(),
            )
        # fallback: stiffer penalties and wider targets (eq. (9): c_n is "a larger value")
        wts = RefineWeights(
            c_d=wts.c_d * 10.0,
            c_k=wts.c_k * 10.0,
            clear_margin_m=wts.clear_margin_m * 1.5 + 0.05,
            k_target=wts.k_target * 0.9,
        )
    marks.update(fit_s=fit_s, check_s=check_s)
    why = chk.reason if chk is not None else "no refinement round ran"
    return _no_path(
        f"no feasible curve after {cfg.refine_rounds} refinement rounds: {why}", timing(), waypoints
    )


def _resample(curve: Nurbs, spacing: float) -> FloatArray:
    """Points along the curve about `spacing` apart in parameter (ends included)."""
    u = np.linspace(curve.u_min, curve.u_max, 400)
    pts = curve.evaluate(u, n_ders=0)[0]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    n = max(2, math.ceil(s[-1] / spacing) + 1)
    at = np.linspace(0.0, s[-1], n)
    return np.stack([np.interp(at, s, pts[:, 0]), np.interp(at, s, pts[:, 1])], axis=1)
