"""Metrics of an AUV run, computed from its record against truth (DESIGN.md "Metrics of a run")."""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable
from typing import Any, NotRequired, TypedDict

import numpy as np

from common.config.scenario import Scenario
from common.estimate_error import estimate_errors
from common.messages import (
    LinkStats,
    ObstacleTracks,
    PathMsg,
    StateEstimate,
    TruthState,
    VehicleStatus,
    VelocityCommand,
)
from common.runtime.model.dataflow import qualified
from common.runtime.model.record import Record, trajectory_sha256
from common.world import ObstacleState, World
from common.world.geometry import nearest_distances
from services.mission.continuity import follows, reach_mps
from services.mission.dataflow import commander
from services.mission.outcome import classify
from services.mission.records import AuvMetrics, build
from services.mission.reentry import reentries
from services.planner.geometry.planned_path import curve_of
from services.planner.reasons import PLANS_DECLINED

# A control action counts as "on the optimal path" (paper §4.1) when the true vehicle is
# within this distance of the first planned path at the moment the command is issued.
ON_PATH_TOL_M = 0.5
# executed curvature |w| / v is only meaningful while the vehicle actually moves
MIN_SPEED_FOR_CURVATURE = 0.3
# `max_executed_curvature_after_start` leaves out the start-up: the first START_UP_S
# seconds after the vehicle first moves in that sense (v > MIN_SPEED_FOR_CURVATURE)
START_UP_S = 1.0
# eq. (11)'s turning bound |w| <= |v| / R_min counts as broken when |w| exceeds |v| / R_min
# by more than this yaw rate: 1.7 % of the bound at cruise speed (0.3 rad/s), and more than
# |v| / R_min changes in one 0.05 s truth period at the acceleration limit (0.3 m/s^2 * 0.05
# s / 5 m = 0.003 rad/s): a plant that bounds w by a speed one period old still passes.
YAW_RATE_TOL_RPS = 0.005
# the two-sided 95 % band of a chi-square with 3 degrees of freedom: the NEES of (x, y, theta)
# of a consistent filter lies in it 95 % of the time
NEES_BAND = (0.2158, 9.3484)
# `tracking_ahead_*` set a track, extrapolated as the planner extrapolates it (eq. (12)), this
# far ahead against where its obstacle then is: about the look-ahead of a replan's pass
TRACK_AHEAD_S = 2.0

# some of AuvMetrics' fields by name, as each part of the metrics computes them; every name
# and value is checked against the record's fields when mission_metrics builds it
Fields = dict[str, object]


def path_points(p: PathMsg, n: int = 4000) -> np.ndarray:
    """Dense samples of a planned NURBS path, (n, 2)."""
    curve = curve_of(p)
    u = np.linspace(curve.u_min, curve.u_max, n)
    return np.asarray(curve.evaluate(u, n_ders=0)[0])


def distinct_paths(paths: Iterable[PathMsg]) -> list[PathMsg]:
    """Each path once, as first sent: with the controller onboard the planner sends the path in
    force again until a newer one (services/planner/repeat.py)."""
    seen: set[int] = set()
    out = []
    for p in paths:
        if p.path_id not in seen:
            seen.add(p.path_id)
            out.append(p)
    return out


def _typed(record: Record, service: str, stream: str, cls: type) -> list[Any]:
    return [m for m in record.stream(service, stream) if isinstance(m, cls)]


def _by_reason(counters: dict[str, int]) -> dict[str, int]:
    """The planner's declined plans by reason code ("plans_declined.<code>" counters)."""
    head = PLANS_DECLINED + "."
    return {k[len(head) :]: n for k, n in sorted(counters.items()) if k.startswith(head)}


def _counts(codes: Iterable[str]) -> dict[str, int]:
    """How often each code occurs, by code."""
    return dict(sorted(Counter(codes).items()))


def last_counters(record: Record, service: str) -> dict[str, int]:
    """The counters of a service's last statistics (a restarted process counts afresh);
    none without statistics."""
    last = record.last_of(service, "stats", LinkStats)
    return dict(last.counters) if last is not None else {}


def mission_metrics(record: Record, s: Scenario, world: World, vehicle: str = "") -> AuvMetrics:
    """Every metric of the run (the runtime adds end reason, link stats, timing); of
    one fleet vehicle's services ("<vehicle>.<service>") when `vehicle` is given, with `s`
    that vehicle's scenario (Scenario.member)."""

    def at(service: str) -> str:
        return qualified(vehicle, service) if vehicle else service

    truth: list[TruthState] = _typed(record, at("vehicle"), "truth", TruthState)
    m: Fields = {
        "trajectory_sha256": trajectory_sha256(truth),
        "controller": s.controller.kind,
    }
    if not truth:
        m |= {"reached_goal": False, "outcome": "not_reached", "success": False}
        return build(AuvMetrics, m)
    arr = np.array([(q.stamp, q.x, q.y, q.theta, q.v) for q in truth])
    t, x, y, theta, v = arr[:, 0], arr[:, 1], arr[:, 2], arr[:, 3], arr[:, 4]
    g, st = s.world.goal, s.world.start
    dist_goal = np.hypot(x - g.x_m, y - g.y_m)
    arrival = _arrival(truth, dist_goal <= s.world.goal_tolerance_m, reach_mps(s))
    end = len(t) - 1 if arrival is None else arrival
    seg = np.hypot(np.diff(x[: end + 1]), np.diff(y[: end + 1]))
    length = float(seg.sum())
    straight = math.hypot(g.x_m - st.x_m, g.y_m - st.y_m)
    travel = float(t[end] - t[0])
    m.update(
        {
            "reached_goal": arrival is not None,
            "travel_time_s": travel,  # eq. (21): Rtime = Rdist / Rspace (= length / mean speed)
            "mean_speed_mps": length / travel if travel > 0 else 0.0,
            "path_length_m": length,
            "f_l_executed": length / straight if straight > 0 else math.nan,
            "final_distance_to_goal_m": float(dist_goal[-1]),
        }
    )
    clear = world.clearance_many(x, y, s.vehicle.radius_m, t)
    safety = _safety_metrics(t, clear, s.planner.rho0_m)
    m.update(safety)
    m["outcome"] = outcome = classify(
        reached_goal=arrival is not None,
        contact=safety["collisions"] > 0,
        below_rho0=safety["rho0_breach_m"] > 0.0,
    )
    # paper §4 success, with eq. (6)'s safety distance as part of it
    m["success"] = outcome == "success"
    m.update(_curvature_metrics(t, x, y, theta, v, s.vehicle.turn_radius_min_m))
    m.update(_path_metrics(record, at("planner"), at(commander(s)), t, x, y, end))
    m.update(_estimation_metrics(record, at("estimator"), truth))
    m.update(_tracking_metrics(record, at("estimator"), world, s.planner.accel_horizon_s, t))
    statuses: list[VehicleStatus] = _typed(record, at("vehicle"), "status", VehicleStatus)
    if statuses:
        last = statuses[-1]
        dt = s.vehicle.period_s
        m.update(
            {
                "commands_applied": last.commands_applied,
                "commands_rejected": last.commands_rejected,
                "commands_rejected_stale": last.rejected_by_reason.get("stale", 0),
                # by reason: services/vehicle/watchdog.py REJECTIONS
                "commands_rejected_by_reason": dict(last.rejected_by_reason),
                "commands_clamped": last.commands_clamped,
                "hold_time_s": dt * sum(1 for q in statuses if q.mode == "HOLD"),
                "failsafe_time_s": dt * sum(1 for q in statuses if q.mode == "FAILSAFE"),
                "hold_distance_max_m": _hold_distance_max(statuses, t, x, y),
            }
        )
    return build(AuvMetrics, m)


def duration_s(t: np.ndarray, when: np.ndarray) -> float:
    """Time during which `when` held: each truth state t: (n,) holds until the next one."""
    return float(np.sum(np.diff(t)[when[:-1]]))


class Safety(TypedDict):
    """AuvMetrics' contact and safety-distance fields."""

    min_clearance_m: float
    min_clearance_t_s: float
    collisions: int
    time_in_contact_s: float
    rho0_m: float
    rho0_breach_m: float
    time_below_rho0_s: float
    first_contact_t_s: NotRequired[float]


def _safety_metrics(t: np.ndarray, clear: np.ndarray, rho0_m: float) -> Safety:
    """Contact and eq. (6)'s safety distance, from the hull-to-obstacle-surface clearance
    clear: (n,) of every truth state (eq. 12, the same geometry the planner keeps rho0 in)."""
    collided = clear < 0.0
    below = clear < rho0_m
    out: Safety = {
        "min_clearance_m": float(clear.min()),
        "min_clearance_t_s": float(t[int(np.argmin(clear))]),  # where to look in a recording
        "collisions": int(np.count_nonzero(collided[1:] & ~collided[:-1]) + int(collided[0])),
        "time_in_contact_s": duration_s(t, collided),
        "rho0_m": rho0_m,
        # how deep inside rho0 the hull came (more than rho0 once in contact); 0 if never
        "rho0_breach_m": max(0.0, rho0_m - float(clear.min())),
        "time_below_rho0_s": duration_s(t, below),
    }
    if out["collisions"]:
        out["first_contact_t_s"] = float(t[np.argmax(collided)])
    return out


def _curvature_metrics(
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    theta: np.ndarray,
    v: np.ndarray,
    turn_radius_min_m: float,
) -> Fields:
    """The turns the vehicle made, measured from its true trajectory t, x, y, theta, v: (n,).

    The hull's turn: its heading's rate over each truth period (from the headings, not the
    plant's yaw-rate state: the unicycle plant bounds that state by v / R_min by
    construction, the REMUS 100's does not), against its speed through the water v; time
    beyond eq. (11)'s turning bound |rate| <= v / R_min. Over ground, the track's curvature
    from the positions (a current bends it: tighter heading into the current, wider with it).
    """
    dt = np.diff(t)
    rate = np.zeros(len(t))
    rate[:-1] = np.diff(np.unwrap(theta)) / np.where(dt > 0.0, dt, np.inf)  # over [t_i, t_i+1]
    moving = v > MIN_SPEED_FOR_CURVATURE
    curv = np.abs(rate[moving]) / v[moving]
    started = t[moving][0] + START_UP_S if moving.any() else math.inf
    after = curv[t[moving] >= started]
    # no speed gate here: at v = 0 a turn is one on the spot, the tightest turn of all
    above = np.abs(rate) - np.abs(v) / turn_radius_min_m > YAW_RATE_TOL_RPS
    out: Fields = {
        "max_executed_curvature": float(curv.max()) if len(curv) else 0.0,
        "max_executed_curvature_after_start": float(after.max()) if len(after) else 0.0,
        "time_above_curvature_limit_s": duration_s(t, above),
    }
    if len(t) >= 3:
        vx, vy = np.gradient(x, t), np.gradient(y, t)
        ax, ay = np.gradient(vx, t), np.gradient(vy, t)
        speed = np.hypot(vx, vy)
        over = (speed > MIN_SPEED_FOR_CURVATURE) & (t >= started)
        k = np.abs(vx * ay - vy * ax)[over] / speed[over] ** 3
        out["max_ground_curvature"] = float(k.max()) if len(k) else 0.0
    return out


def _arrival(truth: list[TruthState], near: np.ndarray, speed_mps: float) -> int | None:
    """Index of the first state within the goal tolerance that follows its predecessor (a
    forged state at the goal does not count, services/mission/continuity.py); None if none."""
    for i in np.flatnonzero(near):
        if i > 0 and follows(truth[i - 1], truth[i], speed_mps):
            return int(i)
    return None


def _hold_distance_max(
    statuses: list[VehicleStatus], t: np.ndarray, x: np.ndarray, y: np.ndarray
) -> float:
    """The longest distance the vehicle travelled in one spell of HOLD/FAILSAFE (without a
    command: blind), from the truth states published with those statuses (same stamps)."""
    blind = {q.stamp for q in statuses if q.mode in ("HOLD", "FAILSAFE")}
    seg = np.hypot(np.diff(x), np.diff(y))
    best = run = 0.0
    for i, stamp in enumerate(t[1:]):
        run = run + float(seg[i]) if stamp in blind else 0.0
        best = max(best, run)
    return best


def _path_metrics(
    record: Record,
    planner: str,
    cmd_source: str,
    t: np.ndarray,
    x: np.ndarray,
    y: np.ndarray,
    end: int,
) -> Fields:
    paths = distinct_paths(_typed(record, planner, "path", PathMsg))
    cmds: list[VelocityCommand] = _typed(record, cmd_source, "cmd", VelocityCommand)
    ok = [p for p in paths if p.status == "OK"]
    out: Fields = {
        "replans": len(paths),
        "no_path_events": sum(1 for p in paths if p.status == "NO_PATH"),
        # precautionary replans whose result was declined, the path in force kept (no path
        # message: the planner counts them, services/planner/adoption.py)
        "plans_declined": last_counters(record, planner).get(PLANS_DECLINED, 0),
        # ... by the rule that declined them (services/planner/decline.py), and the paths
        # published by why they were asked (the replan policy's reason, replan.py)
        "plans_declined_by_reason": _by_reason(last_counters(record, planner)),
        "replans_by_reason": _counts(p.reason.split(":")[0] for p in paths),
        "control_actions": len(cmds),
    }
    if any(p.strategy for p in paths):  # (a recording from before the codes has none)
        # the plans by the strategy that made them (services/planner/reasons.py), and the
        # strategies that ran before and did not give them
        out["plan_strategies"] = _counts(p.strategy for p in paths if p.strategy)
        out["plan_strategies_rejected"] = _counts(c for p in paths for c in p.rejected)
    if not ok:
        return out
    first = ok[0]  # the "optimal path": planned at the start with the whole chart
    optimal = path_points(first)
    xte = nearest_distances(np.column_stack([x[: end + 1], y[: end + 1]]), optimal)
    out.update(
        {
            "planned_length_m": first.length,
            "planned_f_l": first.f_l,
            "planned_max_curvature": first.max_curvature,
            "xte_optimal_rms_m": float(np.sqrt(np.mean(xte**2))),
            "xte_optimal_max_m": float(np.max(xte)),
            # the paper's fuzzy-PID count: returns into the band around the optimal path
            "path_reentries": reentries(xte, ON_PATH_TOL_M),
        }
    )
    # cross-track error against the path in force at each moment
    stamps = np.array([p.stamp for p in ok])
    which = np.searchsorted(stamps, t[: end + 1], side="right") - 1
    errs = np.full(end + 1, np.nan)
    for i, p in enumerate(ok):
        sel = np.flatnonzero(which == i)
        if len(sel) and p is first:  # the same points against the same samples: xte's values
            errs[sel] = xte[sel]
        elif len(sel):
            errs[sel] = nearest_distances(np.column_stack([x[sel], y[sel]]), path_points(p))
    errs = errs[~np.isnan(errs)]
    if len(errs):
        out["xte_planned_rms_m"] = float(np.sqrt(np.mean(errs**2)))
        out["xte_planned_max_m"] = float(np.max(errs))
    # paper §4.1: control actions, and how many were issued while on the optimal path
    if cmds:
        ct = np.array([c.stamp for c in cmds])
        cx, cy = np.interp(ct, t, x), np.interp(ct, t, y)
        d = nearest_distances(np.column_stack([cx, cy]), optimal)
        out["control_actions_on_path"] = int(np.count_nonzero(d <= ON_PATH_TOL_M))
    return out


def _estimation_metrics(record: Record, estimator: str, truth: list[TruthState]) -> Fields:
    """Estimate against truth at each estimate's stamp (common/estimate_error.py, which the
    monitor and Foxglove share): position error, heading error, the current's error, and the
    filter's consistency, NEES of (x, y, theta) against its own covariance (3 dof: the
    chi-square 95 % band is NEES_BAND)."""
    est: list[StateEstimate] = _typed(record, estimator, "state", StateEstimate)
    errors = estimate_errors(est, truth)
    if not errors.scored:
        return {}
    err, pos, dc = errors.error, errors.position_m, errors.current_mps
    cov = np.array([e.covariance for e in errors.scored]).reshape(-1, 5, 5)[:, :3, :3]
    nees = _nees(err, cov)
    ok = np.isfinite(nees)
    return {
        "estimation_rms_m": float(np.sqrt(np.mean(pos**2))),
        "estimation_max_m": float(pos.max()),
        "heading_error_rms_rad": float(np.sqrt(np.mean(err[:, 2] ** 2))),
        "current_error_rms_mps": float(np.sqrt(np.mean(dc**2))),
        "nees_mean": float(np.mean(nees[ok])) if ok.any() else None,
        # the share of the run's estimates whose NEES lies within the 95 % band
        "nees_in_band": float(np.mean((nees[ok] >= NEES_BAND[0]) & (nees[ok] <= NEES_BAND[1])))
        if ok.any()
        else None,
    }


def _nees(err: np.ndarray, cov: np.ndarray) -> np.ndarray:
    """err_i' cov_i^-1 err_i for each i (err: (n, 3), cov: (n, 3, 3)); NaN where cov_i is
    singular (a degenerate covariance says nothing of consistency)."""
    nees = np.full(len(err), np.nan)
    try:
        # all n systems in one call (LAPACK's gesv on each, as one at a time: the same bits)
        sol = np.linalg.solve(cov, err[:, :, None])[:, :, 0]
    except np.linalg.LinAlgError:  # some cov_i is singular: solve them one at a time
        for i in range(len(nees)):
            try:
                nees[i] = float(err[i] @ np.linalg.solve(cov[i], err[i]))
            except np.linalg.LinAlgError:
                continue
        return nees
    for i in range(len(nees)):
        nees[i] = float(err[i] @ sol[i])  # the 3-term dot as before, not reordered
    return nees


def _tracking_metrics(
    record: Record, estimator: str, world: World, accel_horizon_s: float, t: np.ndarray
) -> Fields:
    """How well the published tracks follow the world's moving obstacles (not other hulls):
    position error at each track's stamp, and of the position it extrapolates TRACK_AHEAD_S on
    against where the obstacle then is (what replans pass by). Coasting tracks count: they
    are what the planner has. With moving obstacles in the world the keys are always there
    (a run's key set does not depend on how far it got), null while nothing was measured."""
    # only the moving obstacles are compared: the static ones are not built (their messages,
    # checked as they are built, cost more than the comparisons at every published track)
    moving = {o.id for o in world.moving_at(float(t[0]))}
    if not moving:
        return {}
    now: list[float] = []
    ahead: list[float] = []
    # the obstacles by id at a time: a track's `later` is mostly a later track's `now` (tracks
    # come every 0.1 s, TRACK_AHEAD_S after one is nearly always another's stamp exactly)
    known: dict[float, dict[int, ObstacleState]] = {}

    def obstacles_at(t_s: float) -> dict[int, ObstacleState]:
        got = known.get(t_s)
        if got is None:
            got = known[t_s] = {o.id: o for o in world.moving_at(t_s)}
        return got

    for msg in _typed(record, estimator, "tracks", ObstacleTracks):
        mine = [k for k in msg.tracks if k.id in moving]
        if not mine or not t[0] <= msg.stamp <= t[-1]:
            continue
        truth = obstacles_at(msg.stamp)
        later_t = msg.stamp + TRACK_AHEAD_S
        later = obstacles_at(later_t) if later_t <= t[-1] else {}
        for k in mine:
            now.append(math.hypot(k.x - truth[k.id].x, k.y - truth[k.id].y))
            if later:
                p = ObstacleState.of_track(k).centre_at(TRACK_AHEAD_S, accel_horizon_s)
                ahead.append(math.hypot(float(p[0]) - later[k.id].x, float(p[1]) - later[k.id].y))
    out: Fields = {}
    for name, errs in (("tracking", now), ("tracking_ahead", ahead)):
        e = np.asarray(errs)
        out[f"{name}_rms_m"] = float(np.sqrt(np.mean(e**2))) if errs else None
        out[f"{name}_max_m"] = float(e.max()) if errs else None
    return out
