"""The two rules by which a planner declines a plan it made and keeps the path in force.

Each rule returns a `Declined` (a reason code and what the log says) or None. `overtaken`:
a plan made later than the time it starts (realtime only: a plan of seconds on a loaded
machine) that the vehicle, going on meanwhile, has left. `keeps_path_in_force`: a plan asked
as a precaution that found only a recovery or none, or a NO_PATH while the vehicle steps aside.
`keeps_safer_path`: a plan for a conflict ahead whose own rollout breaks its clearance sooner
than the path in force, cut short of that conflict, can be followed.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import Literal

from services.control.command.link import Prediction
from services.planner.asking import Asked
from services.planner.replan import ReplanPolicy, deviation_near_start
from services.planner.result import PlanResult, Pose2D
from services.planner.shaping.path_arc_reference import PathArcReference

log = logging.getLogger("tidelink.planner")

# a plan made too late (realtime) that would turn the vehicle by more than this where it
# would have it by now is declined (`overtaken`): with R_min it cannot join it there
STALE_HEADING_RAD = math.radians(45.0)
# replans asked while the path in force is still feasible (replan.py): their result replaces
# it only if it is an ordinary plan (`keeps_path_in_force`). "current" too: the policy asks
# it only when the path in force has no conflict, and near an obstacle the wider turning
# radius of a stronger current often leaves only a recovery, whose arc may enter rho0; a
# following current's estimate settling at the start took fuzzy PID into rho0 that way
PRECAUTIONS = ("corridor", "cruise", "current")

# the rules' reason codes (metrics.json plans_declined_by_reason)
DeclineCode = Literal["overtaken", "kept_path_in_force", "kept_safer_path"]


@dataclass(frozen=True, kw_only=True)
class Declined:
    """Why a plan made was declined: a reason code and the sentence the log says."""

    code: DeclineCode
    detail: str


def overtaken(
    t: float,
    pred: Prediction,
    t_plan: float,
    result: PlanResult,
    v_ref: float,
    deviation_threshold_m: float,
) -> Declined | None:
    """Decline a plan made at t (s) for t_plan (s) that the vehicle (predicted: `pred`) has
    left: where the plan, followed at v_ref (m/s), would have it by now, farther from where it
    is than deviation_threshold_m, or heading more than STALE_HEADING_RAD apart. Adopted, the
    controller would steer onto a path checked (and flown) from a place the vehicle is no
    longer at, through water no check covered; the path in force still stops short of its
    conflict, and the next step decides afresh."""
    if not result.ok or t <= t_plan:
        return None
    x, y, theta, v = pred.at_effect[:4]
    ref = PathArcReference(result.planned_path(), v_ref)
    s_then = min(max(v, 0.0) * (pred.effect_t - t_plan), ref.length)
    s_near = ref.closest_s(x, y, s_then)
    px, py = ref.point_at_s(s_near)
    off = math.hypot(x - px, y - py)
    turn = abs(math.remainder(theta - ref.heading_at_s(s_near), 2.0 * math.pi))
    if s_near <= 0.0:  # short of its start, in line: on its way to it
        start = (math.cos(ref.heading_at_s(0.0)), math.sin(ref.heading_at_s(0.0)))
        off = deviation_near_start(Pose2D(x=x, y=y, theta=theta), (px, py), start, off)
        turn = 0.0
    if off <= deviation_threshold_m and turn <= STALE_HEADING_RAD:
        return None
    return Declined(
        code="overtaken",
        detail=f"the vehicle is {off:.2f} m from where it would have it now, heading "
        f"{math.degrees(turn):.0f} deg apart (> {deviation_threshold_m:.2f} m or "
        f"{math.degrees(STALE_HEADING_RAD):.0f} deg)",
    )


def keeps_path_in_force(
    why: str, result: PlanResult, *, has_path: bool, stepping_aside: bool
) -> Declined | None:
    """Decline a plan asked `why` as a precaution (PRECAUTIONS: the path in force was still
    feasible when it was asked) that can only turn about or leave by a recovery, which may
    enter the safety margin, or only go partway (partway.py), or found none: the path in
    force is kept, and the replan check goes on judging it (such a turn about can pass
    inside rho0 of a static obstacle the path in force keeps clear of). And while the
    vehicle steps aside (evade.py), a NO_PATH: it judged going on along the way aside as
    good as any; a way aside is kept until a plan reaches the goal or a better way aside
    is found."""
    if not has_path:
        return None
    if stepping_aside:
        if result.ok:
            return None
    elif why not in PRECAUTIONS or (result.ok and result.escape_m <= 0.0 and not result.partway):
        return None
    what = "a partway plan" if result.partway else "a recovery"
    found = "no path" if not result.ok else f"only {what} ({result.reason})"
    return Declined(code="kept_path_in_force", detail=f"the {why} replan found {found}")


def keeps_safer_path(why: str, result: PlanResult, *, safe_for_s: float) -> Declined | None:
    """Decline a plan asked because the path in force is infeasible ahead (replan.py; the core
    cut it short of the conflict) whose rollout falls short of its clearance sooner (s after
    its start) than the path in force reaches that stop (`safe_for_s`, s; 0 without one): a
    recovery turned about in a squeeze for a moving obstacle's crossing 10-20 s ahead was
    adopted, rollout 0.6 m into rho0 a few seconds on, and flown there. The path in force is
    followed towards its stop while the next checks ask again, from where the way round is
    often clear, and the first plan whose breach comes no sooner than that stop is adopted."""
    if why != "infeasible" or not result.ok or result.flown_short_m <= 0.0:
        return None
    if result.flown_short_at_s >= safe_for_s:
        return None
    return Declined(
        code="kept_safer_path",
        detail=f"its rollout falls {result.flown_short_m:.2f} m short of its clearance "
        f"{result.flown_short_at_s:.1f} s on, the path in force is clear for {safe_for_s:.1f} s",
    )


def decline(
    t: float,
    pred: Prediction,
    asked: Asked,
    result: PlanResult,
    *,
    v_ref: float,
    policy: ReplanPolicy,
    last: PlanResult | None,
    has_path: bool,
    arrived_m: float,
    safe_for_s: float = 0.0,
) -> Declined | None:
    """The first rule that declines the plan `result` made at t (s) for `asked`, logged;
    None: it is adopted. A plan kept out by keeps_path_in_force or keeps_safer_path is told
    to the replan policy, which goes on judging the path in force (`safe_for_s`: how long it
    can be followed, keeps_safer_path)."""
    why = overtaken(t, pred, asked.t_plan, result, v_ref, policy.cfg.deviation_threshold_m)
    if why is None and has_path:
        why = keeps_safer_path(asked.why, result, safe_for_s=safe_for_s)
        if why is not None:
            policy.on_kept(asked.t_plan, asked.obstacles, cut_short=True)
    if why is None:
        # at its end the vehicle stops either way: the NO_PATH is then told (the launcher's
        # alarm on a NO_PATH that lasts), not kept silent behind a way aside run out
        aside = last is not None and last.short_of_goal and policy.remaining_m > arrived_m
        why = keeps_path_in_force(asked.why, result, has_path=has_path, stepping_aside=aside)
        if why is not None:
            policy.on_kept(asked.t_plan, asked.obstacles)
    if why is not None:
        log.info(
            "t=%.2f s: declined the %s plan made for t=%.2f s (%s): %s; the path in force is kept",
            t,
            asked.why,
            asked.t_plan,
            why.code,
            why.detail,
        )
    return why
