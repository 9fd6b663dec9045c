"""A plan's rollout before it is adopted: the controller on the response model, rho0 kept.

The plan keeps the hull rho0 from every obstacle (eq. (12)-(13)) and its turns within R_min
(eq. (20)), but the vehicle flies it with a lag: its yaw rate follows the command with a time
constant and a rate bound, and |w| <= v / R_min leaves no room to catch up on a bend near
R_min. A replan that starts with a turn one way while the vehicle is turning the other way
(its curvature jumps at the start) is flown wide for the whole bend, and can come inside rho0
of an obstacle the plan cleared.

So a plan is flown here first, as the planner's command sequences fly it (sequence.py): the
controller (a copy, reset as on adoption) commands every control period, the response model
(response.py) answers, from the state the plan starts at, twist included, for the whole path
(at most rollout_max_s), in the current believed now and again in the one the estimate may
yet settle to (link.py `doubted_current`; the controller still believes the first). Where
either flight comes inside rho0 + the cushion of an obstacle (past the stretch the plan itself
may pass nearer: escape_m; the cushion is rollout_cushion_m for the model's own error plus
rollout_start_sigmas of the estimate's position std, for the flight starts at the estimate, not
at the truth), the flight's distance off the path there is the
tracking error, and the plan is made again with a clearance margin that wide plus
the cushion, its curvature aimed rollout_curvature_factor lower; if that flight does not
keep rho0 + the cushion either (a squeeze at a bend can be too narrow for the wider
margin), once more around a disc
of rollout_detour_m where the first flight came nearest a static obstacle, so the search takes
another way; and then (that, too, near a static obstacle only) for rollout_slow_factor of the
speed, flown at it. The plan whose flight clears the most is adopted (the first when none
fares better), with the speed it was made for (`PlanResult.v_ref_mps`); either way its
reason says what the flight found. A plan to the goal whose flight keeps rho0 but passes the
goal farther than the mission's goal tolerance (a controller that lags on the last bend, and
then comes about for it, often beyond the area's edge) is made again with gentler bends, then
slower, and the first whose flight arrives is taken. The tunables named here are planner.tuning's
(common/config/planner_tuning.py). Pure: the same floats in every runtime.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from common.config.planner import PlannerConfig
from common.config.planner_tuning import PlannerTuning
from common.config.world import CircleObstacleConfig
from common.world.geometry import FloatArray
from services.control.command.response import Pose, ResponseModel
from services.control.controllers.base import Controller
from services.planner.geometry.clearance import StaticField, moving_distance
from services.planner.reasons import Strategy
from services.planner.result import Obstacles, PlanRequest, PlanResult
from services.planner.safety.intent import IntentObstacle
from services.planner.shaping.path_arc_reference import PathArcReference


@dataclass(frozen=True, kw_only=True)
class RolloutClearance:
    """The clearance report of a rollout: how near a flown path comes to the obstacles,
    where it comes nearest what it must keep
    (`keep_m`: rho0 + rollout_cushion_m, rho0 alone just after an escape): the hull clearance
    there (m), where and when (s after the plan's start), and how far off the path the flight
    was there (its tracking error, m)."""

    min_clearance_m: float
    keep_m: float
    x: float
    y: float
    t_s: float
    off_path_m: float
    path_s_m: float  # the path's arc length (from its start) nearest there
    static: bool = True  # the obstacle nearest there is a static one (else a moving one)
    first_short_s: float = math.inf  # when it first falls short of what it must keep (s)

    @property
    def short_m(self) -> float:
        """How far the flight falls short of what it must keep (<= 0: it keeps it)."""
        return self.keep_m - self.min_clearance_m


@dataclass(frozen=True, kw_only=True)
class RolloutInputs:
    """What a rollout needs from the planner: its controller (copied at the ask: the real one
    goes on stepping), the response model, the control period, the state the plan starts at
    (x, y, theta, v, w) and the mission time then."""

    controller: Controller
    model: ResponseModel
    step_s: float
    start: Pose
    t0: float
    start_std_m: float = 0.0  # how far the start may be off the truth: the estimate's std (m)
    # the model in the stronger current the estimate may yet settle to (link.py
    # `doubted_current`): a plan is flown in it too, and held to the same there
    doubt: ResponseModel | None = None
    # the last rollout flown from these inputs, with the plan, speed and tuning it was flown
    # for: a plan is flown when it is verified and again when checked for contact soon after
    # adoption (asking.py), the same flight
    last_flown: list[tuple[PlanResult, float, PlannerTuning, Rollout]] = field(
        default_factory=list, compare=False, repr=False
    )
    doubt_flown: list[tuple[PlanResult, float, PlannerTuning, Rollout]] = field(
        default_factory=list, compare=False, repr=False
    )
    # the reference of the last plan flown, with its speed: shared with the doubted inputs
    # (`doubted`), which fly the same plan next; a flight only reads it (never `stop_at`)
    last_ref: list[tuple[PlanResult, float, PathArcReference]] = field(
        default_factory=list, compare=False, repr=False
    )

    def doubted(self) -> RolloutInputs | None:
        """These inputs in the doubted current (None without one, or when it is the believed
        one: the same flight)."""
        if self.doubt is None or self.doubt.current_mps == self.model.current_mps:
            return None
        return replace(self, model=self.doubt, doubt=None, last_flown=self.doubt_flown)


@dataclass(frozen=True, eq=False)
class Rollout:
    """A plan's rollout (its flight): its reference, the positions (N, 2) every control
    period, their times
    (s after the start), the distance flown to each, and the state where it ends."""

    ref: PathArcReference
    pts: FloatArray
    t: FloatArray
    dist: FloatArray
    last: Pose
    # its distances to the obstacles and what they were measured among (`_distances`): a plan
    # is measured when it is verified and again when checked for contact soon after adoption
    measured: list[tuple[Obstacles, float, float, FloatArray, FloatArray]] = field(
        default_factory=list, repr=False
    )


def roll_out(
    result: PlanResult, req: PlanRequest, fm: RolloutInputs, tuning: PlannerTuning
) -> Rollout:
    """An OK plan flown (see the module docstring) at req.v_ref_mps: the flight of the last
    call if it was for the same curve (the plan, or one made from it: coded, given its reason),
    speed and tuning (its arrays read-only)."""
    if fm.last_flown:
        plan, v, tun, flown = fm.last_flown[0]
        if plan.same_curve(result) and v == req.v_ref_mps and tun is tuning:
            return flown
    flown = _fly(result, req, fm, tuning)
    for a in (flown.pts, flown.t, flown.dist):
        a.setflags(write=False)
    fm.last_flown[:] = [(result, req.v_ref_mps, tuning, flown)]
    return flown


def _fly(result: PlanResult, req: PlanRequest, fm: RolloutInputs, tuning: PlannerTuning) -> Rollout:
    """roll_out's flight, flown."""
    ref = _reference(result, req.v_ref_mps, fm)
    ctrl = copy.deepcopy(fm.controller)
    ctrl.reset()  # as the loop resets it when a new path is put in force (adoption.py)
    pose = fm.start
    ex, ey = ref.point_at_s(ref.length)
    n = max(1, math.ceil(min(tuning.rollout_max_s, 3.0 * ref.length / req.v_ref_mps) / fm.step_s))
    xs, ys, dist = [pose[0]], [pose[1]], [0.0]
    # the loop's constants read once: it runs every control period of the flight (~500 times)
    command, advance, t0, step_s = ctrl.command, fm.model.advance, fm.t0, fm.step_s
    arrived_mps, arrived_m, hypot = tuning.arrived_mps, tuning.arrived_m, math.hypot
    gone = 0.0
    for k in range(n):
        v, w = command(t0 + k * step_s, pose, ref)
        nxt = advance(pose, v, w, step_s)
        gone += hypot(nxt[0] - pose[0], nxt[1] - pose[1])
        dist.append(gone)
        pose = nxt
        xs.append(pose[0])
        ys.append(pose[1])
        if pose[3] < arrived_mps and hypot(pose[0] - ex, pose[1] - ey) < arrived_m:
            break
    pts = np.column_stack([xs, ys])
    t = fm.step_s * np.arange(len(pts), dtype=np.float64)
    return Rollout(ref=ref, pts=pts, t=t, dist=np.asarray(dist), last=pose)


def _reference(result: PlanResult, v_ref_mps: float, fm: RolloutInputs) -> PathArcReference:
    """The arc-length reference of an OK plan at v_ref_mps: the last one built from these
    inputs (or the believed ones of these doubted ones) if it was for the same curve and speed."""
    if fm.last_ref:
        plan, v, ref = fm.last_ref[0]
        if plan.same_curve(result) and v == v_ref_mps:
            return ref
    ref = PathArcReference(result.planned_path(), v_ref_mps)
    fm.last_ref[:] = [(result, v_ref_mps, ref)]
    return ref


def rollout_clearance(
    result: PlanResult,
    req: PlanRequest,
    fm: RolloutInputs,
    cfg: PlannerConfig,
    within_s: float = math.inf,
) -> RolloutClearance:
    """Fly an OK plan (see the module docstring) and measure its clearance against what it
    must keep, over its first within_s seconds, in the believed current and in the doubted
    one (`RolloutInputs.doubt`): the report of the flight that falls shorter."""
    f = _clearance(result, req, fm, cfg, within_s)
    doubted = fm.doubted()
    if doubted is None:
        return f
    g = _clearance(result, req, doubted, cfg, within_s)
    return g if g.short_m > f.short_m else f


def _clearance(
    result: PlanResult, req: PlanRequest, fm: RolloutInputs, cfg: PlannerConfig, within_s: float
) -> RolloutClearance:
    """rollout_clearance of one flight."""
    f = roll_out(result, req, fm, cfg.tuning)
    ref, pts, t, gone = f.ref, f.pts, f.t, f.dist
    d_static, d = _distances(f, req.obstacles, cfg)
    d = d.copy()
    d[t > within_s] = math.inf
    clearance = d - req.vehicle_radius_m
    # an escape ends at rho0 + 1 cm and the plan leaves the margin gradually after it: for a
    # turning radius on, rho0 alone is kept; beyond, the cushion too (held to rho0 alone for
    # the whole flight, a plan flown off its path well past its escape was adopted as made).
    # A turn first from outside the margin whose arc keeps it has nothing to settle from.
    margin = cfg.rho0_m + cfg.clearance_margin_m
    settles = clearance[0] < margin or result.margin_entered_m > 0.0
    settling = settles & (result.escape_m > 0.0) & (gone < result.escape_m + req.r_min_m)
    cushion = cfg.tuning.rollout_cushion_m
    keep = cfg.rho0_m + np.where(settling, 0.0, kept_cushion_m(fm, cfg.tuning))
    # the plan itself may pass nearer over its escape: from inside the margin, anywhere it
    # must; from outside (a turn first), as far into the margin as the plan's own arc goes,
    # and the cushion
    escaping = gone < result.escape_m
    if clearance[0] < cfg.rho0_m:
        clearance[escaping] = math.inf
    else:
        keep[escaping] = cfg.rho0_m - max(result.margin_entered_m, 0.0) - cushion
    j = int(np.argmin(clearance - keep))
    short = clearance < keep
    x, y = float(pts[j, 0]), float(pts[j, 1])
    s_near = ref.closest_s(x, y, None)
    px, py = ref.point_at_s(s_near)
    return RolloutClearance(
        min_clearance_m=float(clearance[j]),
        keep_m=float(keep[j]),
        x=x,
        y=y,
        t_s=float(t[j]),
        off_path_m=math.hypot(x - px, y - py),
        path_s_m=s_near,
        static=bool(d_static[j] <= d[j]),
        first_short_s=float(t[int(np.argmax(short))]) if short.any() else math.inf,
    )


def _distances(f: Rollout, obs: Obstacles, cfg: PlannerConfig) -> tuple[FloatArray, FloatArray]:
    """A flight's centre distances (N,) to the static obstacles, and to the nearest obstacle
    of all (read-only): those measured before if among the same obstacles and horizons."""
    accel_horizon_s, moving_s = cfg.accel_horizon_s, cfg.tuning.rollout_moving_s
    if f.measured:
        among, accel, soon_s, d_static, d = f.measured[0]
        if among is obs and accel == accel_horizon_s and soon_s == moving_s:
            return d_static, d
    pts, t = f.pts, f.t
    d_static = StaticField.build(obs.circles, obs.polygons).distance(pts)[0]
    d = d_static.copy()
    # another vehicle's broadcast route is its plan, not a guess: it counts over the whole
    # flight, where a head-on pass tens of seconds on is decided (the rest: rollout_moving_s)
    intents = tuple(o for o in obs.moving if isinstance(o, IntentObstacle))
    guessed = tuple(o for o in obs.moving if not isinstance(o, IntentObstacle))
    soon = t <= moving_s
    d[soon] = np.minimum(d[soon], moving_distance(guessed, pts[soon], t[soon], accel_horizon_s)[0])
    d = np.minimum(d, moving_distance(intents, pts, t, accel_horizon_s)[0])
    for a in (d_static, d):
        a.setflags(write=False)
    f.measured[:] = [(obs, accel_horizon_s, moving_s, d_static, d)]
    return d_static, d


def kept_cushion_m(fm: RolloutInputs, tuning: PlannerTuning) -> float:
    """What a rollout keeps past rho0 (m): rollout_cushion_m for the response model's own
    error, and rollout_start_sigmas of the estimate's position std for its start's."""
    return tuning.rollout_cushion_m + tuning.rollout_start_sigmas * fm.start_std_m


Plan = Callable[[PlanRequest, PlannerConfig], PlanResult]


def plan_and_verify(
    req: PlanRequest, cfg: PlannerConfig, fm: RolloutInputs, plan: Plan
) -> PlanResult:
    """`plan(req, cfg)`, flown; made again wider if its flight breaks rho0 (module docstring),
    coded by how it was made again (reasons.py: remade_*), after the plans made before."""
    first = plan(req, cfg)
    if not first.ok:
        return first
    f1 = rollout_clearance(first, req, fm, cfg)
    if f1.short_m <= 0.0:
        return _arriving(first, req, cfg, fm, plan)
    found = (
        f"flown on the response model its hull cleared an obstacle by {f1.min_clearance_m:.2f} "
        f"m (rho0 {cfg.rho0_m:.2f} m) at ({f1.x:.1f}, {f1.y:.1f}) {f1.t_s:.1f} s on, "
        f"{f1.off_path_m:.2f} m off the path"
    )
    wider = replace(
        cfg,
        clearance_margin_m=max(
            cfg.clearance_margin_m, f1.off_path_m + kept_cushion_m(fm, cfg.tuning)
        ),
        curvature_margin=cfg.curvature_margin * cfg.tuning.rollout_curvature_factor,
    )
    tried: list[tuple[str, Strategy, PlanRequest, PlannerConfig]] = [
        (f"made again with a {wider.clearance_margin_m:.2f} m margin", "remade_wider", req, wider)
    ]
    around = _detour(req, cfg, f1)
    if around is not None:
        tried.append(("made again around where it came nearest", "remade_around", around, cfg))
    if f1.static:  # (near a moving obstacle slower would only pass it at another time)
        slower = replace(req, v_ref_mps=req.v_ref_mps * cfg.tuning.rollout_slow_factor)
        tried.append((f"made again for {slower.v_ref_mps:.2f} m/s", "remade_slower", slower, cfg))
    best, best_f, how, code = first, f1, "", first.strategy
    remade: list[Strategy] = []  # the ways it was made again, in order
    for what, way, q, c in tried:
        again = plan(q, c)
        remade.append(way)
        if not again.ok:
            continue
        # judged among the real obstacles, at the speed it was made for
        f = rollout_clearance(again, replace(req, v_ref_mps=q.v_ref_mps), fm, cfg)
        if q.v_ref_mps != req.v_ref_mps:
            # cruise again a turning radius past where this flight comes nearest
            until = f.path_s_m + req.r_min_m
            again = replace(again, v_ref_mps=q.v_ref_mps, slow_until_m=until)
        if f.short_m < best_f.short_m:
            best, best_f, how, code = again, f, what, way
        if best_f.short_m <= 0.0:
            break
    if best is first:
        first = _short(first.coded(first.strategy, (*first.rejected, *remade)), f1)
        return _with_reason(first, f"{found}; made again, it fared no better")
    kept = "clears" if best_f.short_m <= 0.0 else "comes nearer clearing"
    best = _short(best.coded(code, (*first.tried, *(w for w in remade if w != code))), best_f)
    return _with_reason(
        best,
        f"{found}; {how}, whose flight {kept} {best_f.keep_m:.2f} m (clearance there "
        f"{best_f.min_clearance_m:.2f} m)",
    )


def goal_miss_m(
    result: PlanResult, req: PlanRequest, fm: RolloutInputs, cfg: PlannerConfig
) -> float | None:
    """How far from the goal the rollout of a plan that ends there passes at its nearest (m);
    None for a plan that ends elsewhere (a way aside, a partway plan) and for a rollout that
    ended short of the path's end (at rollout_max_s): not judged."""
    f = roll_out(result, req, fm, cfg.tuning)
    ex, ey = f.ref.point_at_s(f.ref.length)
    if math.hypot(ex - req.goal.x, ey - req.goal.y) > 1e-6:
        return None
    last = f.ref.closest_s(float(f.pts[-1, 0]), float(f.pts[-1, 1]), None)
    if last < f.ref.length - req.vehicle_radius_m - req.goal_tolerance_m:
        return None
    return float(np.hypot(f.pts[:, 0] - req.goal.x, f.pts[:, 1] - req.goal.y).min())


def _arriving(
    first: PlanResult, req: PlanRequest, cfg: PlannerConfig, fm: RolloutInputs, plan: Plan
) -> PlanResult:
    """A plan whose rollout keeps its clearance, made again if the rollout passes the goal
    farther than req.goal_tolerance_m (a controller that lags on the last bend misses the
    goal, and coming about for it costs a loop): with its curvature aimed
    rollout_curvature_factor lower, then for rollout_slow_factor of the speed; the first whose
    rollout keeps the clearance and arrives."""
    if req.goal_tolerance_m <= 0.0:
        return first
    miss = goal_miss_m(first, req, fm, cfg)
    if miss is None or miss <= req.goal_tolerance_m:
        return first
    gentler = replace(
        cfg, curvature_margin=cfg.curvature_margin * cfg.tuning.rollout_curvature_factor
    )
    slower = replace(req, v_ref_mps=req.v_ref_mps * cfg.tuning.rollout_slow_factor)
    tried: list[tuple[str, Strategy, PlanRequest, PlannerConfig]] = [
        ("made again with gentler bends", "remade_wider", req, gentler),
        (f"made again for {slower.v_ref_mps:.2f} m/s", "remade_slower", slower, cfg),
    ]
    remade: list[Strategy] = []
    for what, way, q, c in tried:
        again = plan(q, c)
        remade.append(way)
        if not again.ok:
            continue
        flown = replace(req, v_ref_mps=q.v_ref_mps)
        if rollout_clearance(again, flown, fm, cfg).short_m > 0.0:
            continue
        miss_again = goal_miss_m(again, flown, fm, cfg)
        if miss_again is None or miss_again > req.goal_tolerance_m:
            continue
        if q.v_ref_mps != req.v_ref_mps:  # slow to the goal: no cruise replan on the way
            again = replace(again, v_ref_mps=q.v_ref_mps, slow_until_m=again.length_m)
        again = again.coded(way, (*first.tried, *remade[:-1]))
        return _with_reason(
            again,
            f"flown on the response model it passed the goal {miss:.2f} m off (tolerance "
            f"{req.goal_tolerance_m:.2f} m); {what}, it arrives ({miss_again:.2f} m)",
        )
    return first.coded(first.strategy, (*first.rejected, *remade))


def _detour(req: PlanRequest, cfg: PlannerConfig, f: RolloutClearance) -> PlanRequest | None:
    """The request with a disc of rollout_detour_m where a flight came nearest a static
    obstacle: the search then leaves the squeeze (a gap at a bend) for another way. None when
    that was a moving obstacle (it will be elsewhere) or the disc would crowd the start or goal."""
    if not f.static:
        return None
    t = cfg.tuning
    reach = t.rollout_detour_m + req.vehicle_radius_m + cfg.rho0_m + t.rollout_cushion_m
    for p in (req.start, req.goal):
        if math.hypot(p.x - f.x, p.y - f.y) < reach:
            return None
    obs = req.obstacles
    ids = [c.id for c in obs.circles] + [q.id for q in obs.polygons] + [m.id for m in obs.moving]
    disc = CircleObstacleConfig(
        id=max(ids, default=0) + 1, x_m=f.x, y_m=f.y, radius_m=t.rollout_detour_m
    )
    return replace(req, obstacles=replace(obs, circles=(*obs.circles, disc)))


def _short(result: PlanResult, f: RolloutClearance) -> PlanResult:
    """The result with how far and when its rollout `f` falls short (PlanResult.flown_short_m)."""
    if f.short_m <= 0.0:
        return result
    return replace(result, flown_short_m=f.short_m, flown_short_at_s=f.first_short_s)


def _with_reason(result: PlanResult, note: str) -> PlanResult:
    return replace(result, reason=f"{result.reason}; {note}" if result.reason else note)
