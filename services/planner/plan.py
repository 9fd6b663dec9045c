"""The full replan pipeline: cost map, graph search, pruning, NURBS fit, refinement, check.

`plan_path(request, config)` is a pure function: no clock unless one is handed in (only to
fill the timing breakdown), no randomness. A walled-off or unsafe goal, or a curve that
cannot be made to satisfy eq. (12)-(13) and (20), yields status NO_PATH with a reason,
never a colliding path. A start inside the safety margin may leave it within escape_len_m.
Moving obstacles block the search grid around where they are predicted (prediction.py);
when that walls the start off (the vehicle near an obstacle's track) the search runs on the
static field and the refinement and check, exact in time, judge eq. (12)-(13) alone.
Near an obstacle, where no curve leaves the vehicle's pose, the plan recovers (recover.py):
a start in contact first drives out (straight or on an arc within R_min, never deeper); a
heading no curve can leave along first turns away on an arc that keeps the hull free; a
route no curve follows to the goal is followed part of the way (partway.py).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from common.config.planner import PlannerConfig
from common.config.world import AreaConfig
from common.world.geometry import FloatArray
from services.planner.geometry.clearance import StaticField, moving_distance
from services.planner.geometry.nurbs_curve import NurbsCurve
from services.planner.reasons import Strategy
from services.planner.result import (
    Obstacles,
    PlanRequest,
    PlanResult,
    PlanStatus,
    PlanTiming,
    Pose2D,
)
from services.planner.safety.partway import plan_partway
from services.planner.safety.recover import (
    come_about_then_plan,
    leave_then_plan,
    turn_then_plan,
)
from services.planner.search.costmap import CostMap, build_costmap
from services.planner.search.graph import shortest_path
from services.planner.search.prediction import passing_discs, predicted_discs
from services.planner.search.prune import prune_path
from services.planner.shaping.check import CurveCheck, check_curve
from services.planner.shaping.fit import FitProblem, initial_curve, resample
from services.planner.shaping.refine import RefineWeights, refine

__all__ = [
    "Obstacles",
    "PlanRequest",
    "PlanResult",
    "PlanStatus",
    "PlanTiming",
    "Pose2D",
    "plan_path",
]


class _Clock:
    """Accumulates stage durations from an optional injected clock (zero without one)."""

    def __init__(self, clock: Callable[[], float] | None) -> None:
        self.now = clock if clock is not None else (lambda: 0.0)
        self.begin = self.now()
        self.spent = {"costmap_s": 0.0, "search_s": 0.0, "fit_s": 0.0, "check_s": 0.0}
        self.mark = self.begin

    def lap(self, stage: str) -> None:
        t = self.now()
        self.spent[stage] += t - self.mark
        self.mark = t

    def timing(self) -> PlanTiming:
        return PlanTiming(total_s=self.now() - self.begin, **self.spent)


def _no_path(
    reason: str,
    clock: _Clock,
    grid: FloatArray | None = None,
    *,
    code: Strategy,
    rejected: tuple[Strategy, ...] = (),
) -> PlanResult:
    """A NO_PATH for `reason`, coded `code` after the strategies `rejected` (reasons.py)."""
    return PlanResult(
        status="NO_PATH",
        reason=reason,
        strategy=code,
        rejected=rejected,
        grid_path=np.zeros((0, 2)) if grid is None else grid,
        timing=clock.timing(),
    )


def _inside(area: AreaConfig, p: Pose2D, margin: float) -> bool:
    """Is the disc of radius `margin` around p inside the area (eq. (10))?"""
    return (
        area.x_min_m + margin <= p.x <= area.x_max_m - margin
        and area.y_min_m + margin <= p.y <= area.y_max_m - margin
    )


def _unblock_start_goal(
    cmap: CostMap, start: Pose2D, goal: Pose2D, r: float, escape_m: float | None
) -> CostMap:
    """Let the search leave a start that lies inside the safety margin (but not in contact).

    With escape_m set (the start is inside the margin), cells within escape_m of the start
    whose centre keeps the hull off every obstacle become passable (at the capped cost, so
    the path leaves the margin as soon as it can). The start and goal cells themselves are
    always passable: their exact clearance was checked before.
    """
    blocked = cmap.blocked.copy()
    if escape_m is not None:
        xs = cmap.area.x_min_m + (np.arange(cmap.nx) + 0.5) * cmap.resolution_m
        ys = cmap.area.y_min_m + (np.arange(cmap.ny) + 0.5) * cmap.resolution_m
        near = np.hypot(xs[None, :] - start.x, ys[:, None] - start.y) <= escape_m
        blocked &= ~(near & (cmap.clearance > r))
    for p in (start, goal):
        ix, iy = cmap.cell_of(p.x, p.y)
        blocked[iy, ix] = False
    return dataclasses.replace(cmap, blocked=blocked)


def fit_problem(
    req: PlanRequest, cfg: PlannerConfig, static: StaticField, grid: CostMap, *, start_inside: bool
) -> FitProblem:
    """What the curve of a plan for `req` must satisfy (its refinement uses `grid`'s static
    clearance; `start_inside`: the start lies within r + rho0 of an obstacle)."""
    r = req.vehicle_radius_m
    return FitProblem(
        start=req.start,
        goal=req.goal,
        fix_goal_heading=req.fix_goal_heading,
        area=req.area,
        static=static,
        moving=req.obstacles.moving,
        vehicle_radius_m=r,
        r_min_m=req.r_min_m,
        v_ref_mps=req.pace_mps,  # passing times along the curve
        d_req_m=r + cfg.rho0_m,  # eq. (12)-(13): centre-to-surface r + rho0 (r_k in geometry)
        escape_len_m=cfg.escape_len_m,
        start_inside=start_inside,
        accel_horizon_s=cfg.accel_horizon_s,
        grid=grid,
    )


def plan_path(
    req: PlanRequest, cfg: PlannerConfig, clock: Callable[[], float] | None = None
) -> PlanResult:
    """Plan a NURBS path from req.start to req.goal; see the module docstring.

    `clock` (e.g. time.perf_counter) only fills the timing breakdown of the result.
    """
    return _plan(req, cfg, clock, may_escape=True)


@dataclasses.dataclass(frozen=True)
class _Setup:
    """What every stage of one plan shares: the static field and the start's clearance."""

    static: StaticField
    d_start: float  # the start's centre distance to the nearest obstacle (m)
    d_req: float  # eq. (12)-(13): centre-to-surface distance r + rho0 (r_k in geometry)
    d_min: float  # straight-line start-to-goal distance (m), the f_L denominator

    @property
    def start_inside(self) -> bool:
        """Whether the start lies within the safety margin r + rho0 of an obstacle."""
        return self.d_start < self.d_req


Rest = Callable[[PlanRequest], PlanResult]  # the plan after a recovery (never recovers again)

# a goal held with its heading is tried with it free from a start this many R_min from it
GOAL_FREED_R_MIN = 3.0


def _plan(
    req: PlanRequest, cfg: PlannerConfig, clock: Callable[[], float] | None, *, may_escape: bool
) -> PlanResult:
    """plan_path; `may_escape` is False for the plan that follows a recovery (recover.py),
    so one recovery never nests another. The stages, in order: the request's own checks,
    a start outside the area or in contact (a way out first), search and shape (at most
    three searches), then the fallbacks near an obstacle."""
    clk = _Clock(clock)

    def rest(q: PlanRequest) -> PlanResult:
        return _plan(q, cfg, clock, may_escape=False)

    setup = _check_request(req, cfg, clk)
    if isinstance(setup, PlanResult):
        return setup
    stuck = _start_stuck(req, cfg, setup, rest, clk, may_escape=may_escape)
    if stuck is not None:
        return stuck
    result, final = _search_and_shape(req, cfg, setup, clk)
    if final or not may_escape:
        return result
    return _fallbacks(req, cfg, setup, result, rest)


def _check_request(req: PlanRequest, cfg: PlannerConfig, clk: _Clock) -> _Setup | PlanResult:
    """The request's goal and start distances, or a NO_PATH for a goal no plan can reach
    (outside the area, at the start, within rho0 of a static obstacle)."""
    r, obs = req.vehicle_radius_m, req.obstacles
    d_req = r + cfg.rho0_m  # eq. (12)-(13): centre-to-surface distance r + rho0 (r_k in geometry)
    s_xy = np.array([req.start.x, req.start.y])
    g_xy = np.array([req.goal.x, req.goal.y])
    if not _inside(req.area, req.goal, r):
        return _no_path("goal is outside the area", clk, code="goal_refused")
    d_min = float(np.hypot(*(g_xy - s_xy)))
    if d_min < 1e-6:
        return _no_path("start is at the goal: nothing to plan", clk, code="goal_refused")
    static = StaticField.build(obs.circles, obs.polygons)
    d_goal = float(static.distance(g_xy)[0][0])
    if d_goal < d_req:
        return _no_path(
            f"goal lies within the safety distance of a static obstacle "
            f"(hull clearance {d_goal - r:.2f} m < rho0 = {cfg.rho0_m:.2f} m)",
            clk,
            code="goal_refused",
        )
    d_start = min(
        float(static.distance(s_xy)[0][0]),
        float(moving_distance(obs.moving, s_xy, np.zeros(1), cfg.accel_horizon_s)[0][0]),
    )
    return _Setup(static=static, d_start=d_start, d_req=d_req, d_min=d_min)


def _start_stuck(
    req: PlanRequest,
    cfg: PlannerConfig,
    setup: _Setup,
    rest: Rest,
    clk: _Clock,
    *,
    may_escape: bool,
) -> PlanResult | None:
    """For a start outside the area or in contact: a way out then a plan (leave_then_plan,
    then come_about_then_plan), or a NO_PATH; None for a start no search needs to leave."""
    r = req.vehicle_radius_m
    outside = not _inside(req.area, req.start, r)
    if not outside and setup.d_start > r:
        return None
    escaped: PlanResult | None = None
    tried: tuple[Strategy, ...] = ()
    if may_escape:
        escaped = leave_then_plan(req, cfg, setup.static, setup.d_start, rest)
        if escaped is not None and escaped.ok:
            return escaped.coded("escaped_first")
        tried = ("escaped_first",)
        if outside:
            about = come_about_then_plan(req, rest)
            if about is not None and about.ok:
                return about.coded("came_about_first", tried)
            tried, escaped = (*tried, "came_about_first"), about or escaped
    if escaped is None:  # no way out (or, after one, contact again: a moving obstacle)
        where = (
            "outside the area"
            if outside
            else f"in contact with an obstacle (hull clearance {setup.d_start - r:.2f} m)"
        )
        text = f"start is {where} and no way out within R_min is clear"
        return _no_path(text, clk, code="stuck", rejected=tried)
    return escaped.coded(escaped.strategy, tried)  # the NO_PATH after a way out


def _search_and_shape(
    req: PlanRequest, cfg: PlannerConfig, setup: _Setup, clk: _Clock
) -> tuple[PlanResult, bool]:
    """Search the cost map and shape a curve on it, at most three times: once more on the
    static field when the swept discs wall the start off, once more with the obstacles a
    curve met blocked where it passes them. The result, and whether it is final (a plan, or
    a goal walled off); a failed curve is not: the fallbacks may still find one."""
    r, area, obs = req.vehicle_radius_m, req.area, req.obstacles
    s_xy = np.array([req.start.x, req.start.y])
    g_xy = np.array([req.goal.x, req.goal.y])
    escape = cfg.escape_len_m if setup.start_inside else None
    t_max = (
        2.0
        * float(np.hypot(area.x_max_m - area.x_min_m, area.y_max_m - area.y_min_m))
        / req.v_ref_mps
    )
    discs = predicted_discs(obs.moving, req.start, req.pace_mps, t_max, cfg)
    clk.lap("costmap_s")

    rounds = 0
    waypoints = np.zeros((0, 2))
    chk: CurveCheck | None = None
    unswept = passed = False  # each retry below is made at most once (3 searches at most)
    search: Strategy = "searched"  # the search being made, after those `searched`
    searched: tuple[Strategy, ...] = ()
    for _ in range(3):
        cmap = build_costmap(area, setup.static, discs, r, cfg)
        cmap = _unblock_start_goal(cmap, req.start, req.goal, r, escape)
        clk.lap("costmap_s")
        sx, sy = cmap.cell_of(req.start.x, req.start.y)
        gx, gy = cmap.cell_of(req.goal.x, req.goal.y)
        start_i, goal_i = sy * cmap.nx + sx, gy * cmap.nx + gx
        path = shortest_path(cmap, start_i, goal_i, cfg.connectivity, cfg.search)
        if path is None:
            clk.lap("search_s")
            if len(discs) and not unswept:
                # the swept discs, a conservative stand-in for eq. (13), wall the start off
                # near an obstacle's track: search the static field, and let the refinement
                # and the check judge eq. (12)-(13) at the times the curve passes
                discs, unswept = np.zeros((0, 3)), True
                searched, search = (*searched, search), "searched_static"
                continue
            moving = " and moving ones where predicted" if len(discs) else ""
            return _no_path(
                f"goal unreachable: static obstacles{moving}, inflated by r + rho0, wall it off "
                f"from the start on the {cfg.resolution_m:g} m grid",
                clk,
                code="no_route",
                rejected=(*searched, search),
            ), True
        waypoints = prune_path(cmap, path, s_xy, g_xy)
        clk.lap("search_s")
        prob = fit_problem(req, cfg, setup.static, cmap, start_inside=setup.start_inside)
        curve, chk, n, met_moving = _fit_and_check(prob, waypoints, cfg, clk)
        rounds += n
        if chk.ok:
            planned = _planned(curve, chk, waypoints, rounds, setup, cfg, clk)
            return planned.coded(search, searched), True
        if passed or met_moving is None:
            break
        passed = True
        searched, search = (*searched, search), "searched_passing"
        # a curve met a moving obstacle at a time the grid did not predict: block each
        # obstacle around the time that curve passes it, and search again
        discs = np.concatenate([discs, passing_discs(met_moving, obs.moving, req.pace_mps, cfg)])
        clk.lap("fit_s")
    why = chk.reason if chk is not None else "no refinement round ran"
    failed = _no_path(
        f"no feasible curve after {rounds} refinement rounds: {why}",
        clk,
        waypoints,
        code="no_curve",
        rejected=(*searched, search),
    )
    return failed, False


def _planned(
    curve: NurbsCurve,
    chk: CurveCheck,
    waypoints: FloatArray,
    rounds: int,
    setup: _Setup,
    cfg: PlannerConfig,
    clk: _Clock,
) -> PlanResult:
    """The plan of a curve that passed its check."""
    return PlanResult.of_curve(
        curve,
        chk.samples,
        reason="",
        strategy="searched",
        grid_path=waypoints,
        length_m=chk.length_m,
        f_l=chk.length_m / setup.d_min,
        max_curvature=chk.max_curvature,
        min_clearance_m=chk.min_clearance_m,
        turn_penalty=chk.turn_penalty,
        rounds=rounds,
        timing=clk.timing(),
        escape_m=cfg.escape_len_m if setup.start_inside else 0.0,
    )


def _fallbacks(
    req: PlanRequest, cfg: PlannerConfig, setup: _Setup, failed: PlanResult, rest: Rest
) -> PlanResult:
    """After no feasible curve, the recoveries in order, the first plan that is ok kept.
    Near a goal held with its heading, reach it with the heading free. Near an obstacle the
    heading may be what no curve can satisfy (eq. (10) with R_min): turn away on an arc
    within R_min first; inside the margin, failing that, drive out first; a route no curve
    follows to the goal: follow one part of the way (partway.py);
    the area's edge may be what is in the way: come about across it. Each is coded after
    the searches and the recoveries that ran before it (reasons.py)."""
    tried = failed.rejected
    if _near_a_held_goal(req):
        freed = rest(dataclasses.replace(req, fix_goal_heading=False))
        if freed.ok:
            freed = freed.after(failed.reason, "to the goal with its heading free")
            return freed.coded("heading_freed", tried)
        tried = (*tried, "heading_freed")
    turned = turn_then_plan(req, failed, rest, cfg.rho0_m)
    if turned.ok:
        return turned.coded("turned_first", tried)
    tried = (*tried, "turned_first")
    if setup.start_inside:
        escaped = leave_then_plan(req, cfg, setup.static, setup.d_start, rest)
        if escaped is not None and escaped.ok:
            return escaped.coded("escaped_first", tried)
        tried = (*tried, "escaped_first")
    part = plan_partway(req, failed, rest)
    if part is not None:
        return part.coded("partway", tried)
    tried = (*tried, "partway")
    about = come_about_then_plan(req, rest)
    if about is not None and about.ok:
        return about.coded("came_about_first", tried)
    last = failed if setup.start_inside else turned
    return last.coded(last.strategy, (*tried, "came_about_first"))


def _near_a_held_goal(req: PlanRequest) -> bool:
    """The goal's heading is held (eq. (10)) and the start is within GOAL_FREED_R_MIN turning
    radii of it: there a vehicle that came past or beside the goal, often late on its last
    bend, has no curve that joins the heading, and the mission asks only to reach the goal."""
    near = GOAL_FREED_R_MIN * req.r_min_m
    return (
        req.fix_goal_heading
        and math.hypot(req.goal.x - req.start.x, req.goal.y - req.start.y) <= near
    )


def _fit_and_check(
    prob: FitProblem, waypoints: FloatArray, cfg: PlannerConfig, clk: _Clock
) -> tuple[NurbsCurve, CurveCheck, int, NurbsCurve | None]:
    """Fit, then refine and check in rounds.

    Each failed round stiffens the penalties (eq. (9): c_n "a larger value") and tightens
    the targets; the second round continues from the first, the third resamples the last
    curve with twice the control points, later ones start afresh from the waypoints with
    twice as many again; fallback rounds get twice the iterations.
    Returns the last curve, its check, the rounds used and the first curve that failed on
    a moving obstacle (None if none did).
    """
    spacing = cfg.ctrl_spacing_m
    met_moving: NurbsCurve | None = None
    wts = RefineWeights.of(cfg, prob.r_min_m)
    curve = initial_curve(prob, waypoints, spacing, cfg.nurbs_degree)
    for rnd in range(cfg.refine_rounds):
        if rnd >= 2:  # fallback: twice the control points, seeded from the last curve,
            spacing *= 0.5  # or (from the fourth round) afresh from the waypoints
            seed = resample(curve, spacing) if rnd == 2 else waypoints
            curve = initial_curve(prob, seed, spacing, cfg.nurbs_degree)
        curve = refine(
            prob,
            curve,
            wts,
            per_span=cfg.samples_per_span,
            max_iter=cfg.refine_max_iter * (2 if rnd >= 2 else 1),
            method=cfg.refine_method,
        )
        clk.lap("fit_s")
        chk = check_curve(curve, prob, cfg.n_samples_check)
        clk.lap("check_s")
        if chk.ok:
            return curve, chk, rnd + 1, met_moving
        if chk.failed == "moving" and met_moving is None:
            met_moving = curve
        wts = RefineWeights(
            c_d=wts.c_d * 10.0,
            c_k=wts.c_k * 10.0,
            clear_margin_m=wts.clear_margin_m * 1.5 + 0.05,
            k_target=wts.k_target * 0.9,
            c_r=wts.c_r,  # a cost, not a constraint: it keeps its weight
        )
    return curve, chk, cfg.refine_rounds, met_moving
