"""Stepping aside and holding first: out of a moving obstacle's way and of the safety margin.

While no plan, or only a recovery into the margin, is found, the vehicle keeps out of both.

A plan that reaches no goal (NO_PATH) stops the vehicle where it is (CommandLink.follow). That
is safe among static obstacles, but a moving one's track may run through where it stops: the
vehicle brakes on its heading over metres (the speed loop's lag), and the obstacle runs into it.

So when the vehicle, held (its stop flown on the response model: response.py), would come
within rho0 of a moving obstacle (eq. (12)-(13), obstacles where they will be, tracked ones
and other vehicles' intents alike) over the next evade_s, it takes a way aside instead: an
arc no tighter than ARC_RADIUS_FACTOR R_min (as a recovery's, recover.py) turning either way
up to a half turn, then straight, ending every evade_length_step_m up to evade_s at cruise speed,
where the vehicle stops. The ways are swept (escape.py: never into contact, nor out of the
area), each held at its end for the rest of evade_s; the evade_shortlist of them that clear the
most (those that end where a full circle of that radius is free to one side first: stopped
facing an edge or a wall, no curve leaves; then up to rho0 + rollout_cushion_m, then the
shortest, then the smallest turn) are flown by the controller (rollout.py), and the one whose
flight, then held, clears the most (one that stops with room to turn about first) is taken
if it clears evade_gain_m more than holding. Its path ends short of the goal (`short_of_goal`):
the replan policy tries the goal again at every interval (replan.py, `aside`); while it is in
force, what a new way aside must beat is going on along it (core.py keeps it over a NO_PATH
until its end).

It steps aside too when holding is clear of every obstacle but would stop the vehicle where
no such circle keeps rho0 (a wall ahead), while where it is one does (`trapped`: from that
stop only a recovery into the margin turns it about): then the ways that stop with that
room come first, and one is taken if its flight keeps rho0.

And a plan whose recovery turns into the margin (recover.py, `margin_entered_m`) waits while
the vehicle still moves at hold_first_factor of cruise speed or more and holding keeps rho0
with that room: the planner answers NO_PATH ("holds first"), the vehicle brakes, and the
next replans try again from nearer rest, where the moving obstacles that blocked a way
keeping the margin may have passed. Slower than that, holding no longer changes where the
vehicle is, and the recovery is taken.
The tunables named here are planner.tuning's (common/config/planner_tuning.py).
Pure: the same floats in every runtime.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from common.config.planner import PlannerConfig
from common.world.geometry import FloatArray
from services.control.command.response import Pose
from services.planner.geometry.clearance import StaticField, moving_distance
from services.planner.plan import plan_path
from services.planner.result import PlanRequest, PlanResult
from services.planner.safety.escape import (
    DEPTH_STEP_M,
    N_TURNS,
    Escape,
    points_along,
    sweep,
    to_edge,
)
from services.planner.safety.recover import ARC_RADIUS_FACTOR
from services.planner.safety.rollout import (
    RolloutInputs,
    plan_and_verify,
    roll_out,
)


def plan_or_step_aside(
    req: PlanRequest, cfg: PlannerConfig, fm: RolloutInputs, aside: PlanResult | None = None
) -> PlanResult:
    """The plan to the goal, flown (rollout.py), unless it enters the safety margin where
    holding keeps out of it (module docstring: holds first); without one, a way aside when
    holding (or going on along `aside`, the way aside in force) is in a moving obstacle's way
    or traps the vehicle, else the NO_PATH; coded (reasons.py) held_first, stepped_aside or
    as the plan was made, after the strategies that ran before."""
    result = plan_and_verify(req, cfg, fm, plan_path)
    if result.ok:
        moving_on = fm.start[3] >= cfg.tuning.hold_first_factor * req.v_ref_mps
        if result.margin_entered_m <= 0.0 or not moving_on or not req.obstacles.moving:
            return result
        held = _holding(req, cfg, fm, aside)
        if held.threatened or held.trapped:
            return result
        return PlanResult(
            status="NO_PATH",
            reason=f"{result.reason}, {result.margin_entered_m:.2f} m into rho0, where "
            f"{held.how} keeps {held.clear_m:.2f} m: holds first",
            strategy="held_first",
            rejected=result.tried,
            grid_path=result.grid_path,
            timing=result.timing,
        )
    way = step_aside(req, cfg, fm, aside)
    if way is None:
        return result.coded(result.strategy, (*result.rejected, "stepped_aside"))
    return replace(way, reason=f"{result.reason}; {way.reason}", rejected=result.tried)


@dataclass(frozen=True)
class Holding:
    """What holding (or going on along the way aside in force, then holding) comes to over
    evade_s: its least clearance, whether the vehicle then has room to turn about (hull
    free, rho0 kept: `_rooms_at`), and so whether it is in a moving obstacle's way
    (`threatened`) or, clear of every obstacle, would stop where it can no longer turn about
    outside rho0 while where it is now it can (`trapped`)."""

    how: str
    clear_m: float
    rooms: tuple[bool, bool]
    threatened: bool
    trapped: bool


def _holding(
    req: PlanRequest, cfg: PlannerConfig, fm: RolloutInputs, aside: PlanResult | None
) -> Holding:
    static = StaticField.build(req.obstacles.circles, req.obstacles.polygons)
    evade_s = cfg.tuning.evade_s
    if aside is None:
        how = "holding"
        pts, t, stop = _held_on(fm, np.array([fm.start[:2]]), np.zeros(1), fm.start, evade_s)
    else:
        how = "going on along the way aside in force"
        f = roll_out(aside, req, fm, cfg.tuning)
        pts, t, stop = _held_on(fm, f.pts, f.t, f.last, evade_s)
    clear = _clearance((pts, t), req, cfg, static)
    radius = ARC_RADIUS_FACTOR * req.r_min_m
    rooms = _rooms_at(stop, radius, static, req, cfg)
    threatened = clear < cfg.rho0_m
    trapped = not threatened and not rooms[1] and _rooms_at(fm.start, radius, static, req, cfg)[1]
    return Holding(how=how, clear_m=clear, rooms=rooms, threatened=threatened, trapped=trapped)


def step_aside(
    req: PlanRequest, cfg: PlannerConfig, fm: RolloutInputs, aside: PlanResult | None = None
) -> PlanResult | None:
    """A path aside (module docstring), or None when holding, or going on along `aside`,
    is as good."""
    if not req.obstacles.moving:
        return None
    held = _holding(req, cfg, fm, aside)
    if not (held.threatened or held.trapped):
        return None
    static = StaticField.build(req.obstacles.circles, req.obstacles.polygons)
    radius = ARC_RADIUS_FACTOR * req.r_min_m
    ways = _ranked_ways(req, cfg, fm, static, radius, trapped=held.trapped)
    best = _best_flown(ways, req, cfg, fm, static, radius, held)
    if best is None:
        return None
    got, way = best
    why = (
        f"it would come within {held.clear_m:.2f} m of a moving obstacle"
        if held.threatened
        else "it would stop with no room to turn about outside rho0"
    )
    return replace(
        way,
        reason=f"{held.how}, {why}: steps aside {way.length_m:.1f} m (turning "
        f"{math.degrees(way.turn_rad):+.0f} deg), flown clearing {got:.2f} m, then holds",
        min_clearance_m=got,
    )


@dataclass(frozen=True)
class _Ways:
    """The ways aside swept, best first (`ranked`: (turn j, end e) pairs)."""

    turns: FloatArray  # (J,) the turn each way is swept with (rad)
    lengths: FloatArray  # (E,) where the ways end, along them (m)
    score: FloatArray  # (J, E) the least hull clearance on the way and held at its end (m)
    ranked: list[tuple[int, int]]


def _ranked_ways(
    req: PlanRequest,
    cfg: PlannerConfig,
    fm: RolloutInputs,
    static: StaticField,
    radius: float,
    *,
    trapped: bool,
) -> _Ways:
    """The ways aside that never touch nor leave the area, ranked: room to turn about where
    they stop, then (trapped) room outside rho0, then clearance up to rho0 +
    rollout_cushion_m, then the shortest, then the smallest turn."""
    moving = req.obstacles.moving
    r, v = req.vehicle_radius_m, req.v_ref_mps
    turns = np.linspace(-math.pi, math.pi, N_TURNS)
    sw = sweep(
        req.start,
        turns,
        radius,
        v * cfg.tuning.evade_s,
        static,
        moving,
        req.area,
        v_ref=v,
        accel_horizon_s=cfg.accel_horizon_s,
    )
    step_m, evade_s = cfg.tuning.evade_length_step_m, cfg.tuning.evade_s
    ends = np.searchsorted(sw.s, np.arange(step_m, v * evade_s + 1e-9, step_m))
    ends = ends[ends < len(sw.s)]
    free = sw.deeper(r, r)[:, ends] <= 1e-9  # (J, E) never into contact, nor out of the area
    on_way = np.minimum.accumulate(sw.d, axis=1)[:, ends]  # (J, E) the least on the way there
    # held at its end from when it gets there (at cruise speed) to evade_s
    t_hold = np.arange(0.0, evade_s + 1e-9, fm.step_s)
    end_pts = points_along(req.start, turns, radius, sw.s[ends])  # (J, E, 2)
    flat = np.repeat(end_pts.reshape(-1, 2), len(t_hold), axis=0)
    d_end = moving_distance(
        moving, flat, np.tile(t_hold, len(turns) * len(ends)), cfg.accel_horizon_s
    )[0].reshape(len(turns), len(ends), len(t_hold))
    arrive = sw.s[ends] / v  # (E,)
    d_end = np.where(t_hold[None, None, :] >= arrive[None, :, None], d_end, np.inf).min(axis=2)
    score = np.minimum(on_way, d_end) - r  # (J, E)
    # where it stops it must be able to turn about, as a recovery turns (recover.py), to
    # plan on from there: stopped facing an edge or a wall, no forward curve leaves
    heading = req.start.theta + np.sign(turns)[:, None] * np.minimum(
        np.abs(turns)[:, None], sw.s[ends][None, :] / radius
    )  # (J, E)
    room = _turning_room(end_pts, heading, radius, r, static, req)
    # trapped: ways that leave room to turn about outside rho0 come next (else all alike)
    room_kept = _turning_room(end_pts, heading, radius, r + cfg.rho0_m, static, req) | (not trapped)
    cap = cfg.rho0_m + cfg.tuning.rollout_cushion_m
    # a way that ends on its arc is the same as any larger turn's up to there: one of each
    ways = {
        (_turn(float(turns[j]), float(sw.s[ends[e]]), radius), int(e)): (int(j), int(e))
        for j, e in zip(*np.nonzero(free), strict=True)
    }
    cands = sorted(
        ways.values(),
        key=lambda je: (
            not room[je],
            not room_kept[je],
            -round(min(float(score[je]), cap) / DEPTH_STEP_M),
            float(sw.s[ends[je[1]]]),
            abs(float(turns[je[0]])),
        ),
    )
    return _Ways(turns=turns, lengths=sw.s[ends], score=score, ranked=cands)


def _best_flown(
    ways: _Ways,
    req: PlanRequest,
    cfg: PlannerConfig,
    fm: RolloutInputs,
    static: StaticField,
    radius: float,
    held: Holding,
) -> tuple[float, PlanResult] | None:
    """Of the evade_shortlist best ways, the one whose flight, then held, clears the most (one
    that stops with room to turn about first), with that clearance, if it beats holding."""
    best: tuple[tuple[bool, bool], float, PlanResult] | None = None
    for j, e in ways.ranked[: cfg.tuning.evade_shortlist]:
        length = float(ways.lengths[e])
        esc = Escape(
            start=req.start,
            radius_m=radius,
            turn_rad=_turn(float(ways.turns[j]), length, radius),
            length_m=length,
            start_clearance_m=held.clear_m,
            end_clearance_m=float(ways.score[j, e]),
        )
        way = _as_plan(esc, req, cfg)
        f = roll_out(way, req, fm, cfg.tuning)
        got_pts, got_t, _ = _held_on(fm, f.pts, f.t, f.last, cfg.tuning.evade_s)
        got = _clearance((got_pts, got_t), req, cfg, static)
        # where the flight stops (past the way's end, as the speed loop lags)
        turns_there, kept_there = _rooms_at(f.last, radius, static, req, cfg)
        rooms = (turns_there, kept_there or not held.trapped)
        # better than holding: clearer by evade_gain_m, or (trapped) as clear up to rho0 with room
        gains = got >= held.clear_m + cfg.tuning.evade_gain_m or (
            held.trapped and kept_there and got >= cfg.rho0_m
        )
        if gains and (best is None or (rooms, got) > best[:2]):
            best = (rooms, got, way)
    return None if best is None else (best[1], best[2])


def _turn(turn: float, length: float, radius: float) -> float:
    """A way that ends on its arc turns only as far as it gets."""
    return float(np.sign(turn)) * min(abs(turn), length / radius)


def _held_on(
    fm: RolloutInputs, pts: FloatArray, t: FloatArray, last: Pose, evade_s: float
) -> tuple[FloatArray, FloatArray, Pose]:
    """Positions pts at times t (a flight, ending in state `last`), then the vehicle stopped
    (the stop command on the response model) every control period up to evade_s; and the
    state it is left in."""
    n = math.ceil((evade_s - float(t[-1])) / fm.step_s)
    if n <= 0:
        return pts, t, last
    pose = last
    more = []
    for _ in range(n):
        pose = fm.model.advance(pose, 0.0, 0.0, fm.step_s)
        more.append((pose[0], pose[1]))
    return (
        np.vstack([pts, np.array(more)]),
        np.concatenate([t, float(t[-1]) + fm.step_s * np.arange(1, n + 1)]),
        pose,
    )


def _rooms_at(
    pose: Pose, radius: float, static: StaticField, req: PlanRequest, cfg: PlannerConfig
) -> tuple[bool, bool]:
    """Whether a vehicle stopped at `pose` has room to turn about (`_turning_room`): with
    its hull free, and keeping the safety margin rho0 (else a recovery's arc enters it)."""
    x, y, th = pose[:3]
    at, heading, r = np.array([[[x, y]]]), np.array([[th]]), req.vehicle_radius_m
    return (
        bool(_turning_room(at, heading, radius, r, static, req)[0, 0]),
        bool(_turning_room(at, heading, radius, r + cfg.rho0_m, static, req)[0, 0]),
    )


def _turning_room(
    ends: FloatArray,
    heading: FloatArray,
    radius: float,
    r: float,
    static: StaticField,
    req: PlanRequest,
) -> np.ndarray:
    """(J, E) whether a full circle of `radius` to either side of each end pose keeps the
    hull free of static obstacles and in the area (eq. (10))."""
    a = np.linspace(0.0, 2.0 * math.pi, 24, endpoint=False)
    ok = np.zeros(ends.shape[:2], dtype=bool)
    for side in (1.0, -1.0):
        cx = ends[..., 0] - side * radius * np.sin(heading)
        cy = ends[..., 1] + side * radius * np.cos(heading)
        px = cx[..., None] + radius * np.cos(a)
        py = cy[..., None] + radius * np.sin(a)
        edge = to_edge(req.area, px, py)
        pts = np.stack([px, py], axis=-1).reshape(-1, 2)
        d = (
            static.distance(pts)[0].reshape(px.shape)
            if not static.empty
            else np.full(px.shape, np.inf)
        )
        ok |= np.all((edge >= r) & (d >= r), axis=-1)
    return ok


def _clearance(
    track: tuple[FloatArray, FloatArray], req: PlanRequest, cfg: PlannerConfig, static: StaticField
) -> float:
    """The least hull clearance of positions at times (s from the request's start) to every
    obstacle (eq. (12)-(13): moving ones where they will be then)."""
    pts, t = track
    d = np.minimum(
        static.distance(pts)[0],
        moving_distance(req.obstacles.moving, pts, t, cfg.accel_horizon_s)[0],
    )
    return float(d.min()) - req.vehicle_radius_m


def _as_plan(esc: Escape, req: PlanRequest, cfg: PlannerConfig) -> PlanResult:
    """A way aside as a path: the exact arc and straight run (escape.py), short of the goal."""
    a = np.array([req.start.x, req.start.y])
    return PlanResult.of_curve(
        esc.curve(cfg.nurbs_degree),
        reason="",
        strategy="stepped_aside",
        grid_path=np.vstack([a, np.array(esc.point_at(esc.length_m))]),
        length_m=esc.length_m,
        f_l=0.0,
        max_curvature=1.0 / esc.radius_m if esc.turn_rad else 0.0,
        min_clearance_m=esc.end_clearance_m,
        escape_m=esc.length_m,  # swept clear of contact: the policy judges it by moving ones
        turn_rad=esc.turn_rad,
        short_of_goal=True,
    )
