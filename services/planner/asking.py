"""Asking for a plan: where and when it starts, what it is asked with, and how long plans take.

A plan is made at once (virtual time) or beside the steps (the wall clock), which go on
following the path in force until it is there (common/runtime/deferred.py). So a plan asked
on the path in force starts where the vehicle will be once it is made, as long as the last
plans took; it is asked over ground in the estimated current (R_min widened, the pace along
its way), with the clearance margin widened by the loop's measured delay and the current;
and it is verified by a rollout on the response model before it is adopted (rollout.py).
"""

from __future__ import annotations

import copy
import logging
import math
from collections import deque
from dataclasses import dataclass, replace
from statistics import median

from common.config.planner import PlannerConfig
from common.config.vehicle import VehicleConfig
from common.config.world import WorldConfig
from common.runtime.deferred import Deferred
from services.control.command.link import CommandLink, Prediction
from services.control.controllers.base import Controller, crab_angle
from services.control.controllers.follower import course_over_ground
from services.planner.evade import plan_or_step_aside, step_aside
from services.planner.plan import Obstacles, PlanRequest, PlanResult, Pose2D
from services.planner.safety.rollout import RolloutInputs, rollout_clearance
from services.planner.shaping.path_arc_reference import PathArcReference

log = logging.getLogger("tidelink.planner")

# A plan taking longer than this (mission s) is logged when it is adopted: while it is made,
# the path in force is followed and no other replan can start
SLOW_PLAN_S = 2.0
# the plan durations (mission s) a plan's expected duration is the median of
PLAN_LAGS_KEPT = 3
# a plan made for where the vehicle will be is made for at most this far ahead (s)
PLAN_AHEAD_MAX_S = 10.0
# replans that start from where the vehicle is on its path (not off it, nor after a silence)
_ALONG_THE_PATH = ("infeasible", "corridor", "cruise", "aside", "goal_changed", "current")


@dataclass(frozen=True, kw_only=True)
class Asked:
    """What a plan was asked for: the time it plans for, the obstacles then, and why; and the
    step that asked (`asked_t`)."""

    t_plan: float
    obstacles: Obstacles
    why: str
    asked_t: float
    current: tuple[float, float] = (0.0, 0.0)  # the current it is flown in
    pace: float = 1.0  # speed over ground per speed through the water on its way


@dataclass(frozen=True, kw_only=True)
class PlanAsk:
    """What one plan is made with: the request `req` (its R_min the one over ground in the
    current: `PlanAsking.ground_turn_radius_m`), the hull's own R_min through the water
    `r_water_m` (m), the config with the clearance margin in force, the rollout inputs it is
    verified with (rollout.py), and the way aside in force (evade.py; None: none)."""

    req: PlanRequest
    r_water_m: float
    cfg: PlannerConfig
    rollout: RolloutInputs
    aside: PlanResult | None = None


def _plan_over_ground(ask: PlanAsk) -> PlanResult:
    """The plan for ask.req, whose R_min is the one over ground in the current (wider than the
    hull's); failing that, one within the hull's own R_min r_water_m: its bends with the
    current may be flown wide (its rollout says so), but a path is better than none, which in
    a current leaves the vehicle to drift (coded hull_turns)."""
    req, cfg, rollout, aside = ask.req, ask.cfg, ask.rollout, ask.aside
    result = plan_or_step_aside(req, cfg, rollout, aside)
    if result.ok or req.r_min_m <= ask.r_water_m:
        return result
    tighter = plan_or_step_aside(replace(req, r_min_m=ask.r_water_m), cfg, rollout, aside)
    if not tighter.ok:
        return result.coded(result.strategy, (*result.rejected, "hull_turns"))
    return replace(
        tighter,
        reason=f"within the hull's own R_min: {tighter.reason}".rstrip(": "),
        strategy="hull_turns",
        rejected=(*result.rejected, *tighter.rejected),
    )


def plan_clear_of_contact(ask: PlanAsk) -> PlanResult:
    """_plan_over_ground, but never a plan its own rollout (rollout.py) has the hull touch an
    obstacle on: one made again that "fared no better" was adopted, and flown into contact
    (a planner frozen 8 s, issue 61). Then a way aside whose rollout keeps clear, else the
    NO_PATH: the vehicle holds, and the next plan starts from there (declined_contact)."""
    result = _plan_over_ground(ask)
    touch = _flown_clearance(result, ask)
    if touch >= 0.0:
        return result
    why = f"{result.reason}; flown, its hull would touch an obstacle ({touch:.2f} m) soon"
    tried = result.tried
    if not result.short_of_goal:
        way = step_aside(ask.req, ask.cfg, ask.rollout, ask.aside)
        if way is not None and _flown_clearance(way, ask) >= 0.0:
            return replace(way, reason=f"{why}; {way.reason}", rejected=tried)
        tried = (*tried, "stepped_aside")
    return PlanResult(
        status="NO_PATH",
        reason=f"{why}: holds",
        strategy="declined_contact",
        rejected=tried,
        grid_path=result.grid_path,
        timing=result.timing,
    )


def _flown_clearance(result: PlanResult, ask: PlanAsk) -> float:
    """The hull's clearance where an OK plan's rollout comes nearest what it must keep, at the
    speed it was made for, within the first tuning.contact_horizon_s of it (inf for a
    NO_PATH, or beyond): a rollout's guess a minute ahead in a current is no reason to hold
    at the start (the plan is checked again on the way), contact soon after adoption is."""
    if not result.ok:
        return math.inf
    req, cfg = ask.req, ask.cfg
    v = req.v_ref_mps if result.v_ref_mps is None else result.v_ref_mps
    horizon = cfg.tuning.contact_horizon_s
    return rollout_clearance(
        result, replace(req, v_ref_mps=v), ask.rollout, cfg, horizon
    ).min_clearance_m


class PlanAsking:
    """Asks `plans` for a plan (one at a time) and hands back what it was asked for."""

    def __init__(
        self,
        cfg: PlannerConfig,
        vehicle: VehicleConfig,
        world: WorldConfig,
        link: CommandLink,
        plans: Deferred[PlanResult],
        goal: Pose2D,
        *,
        fix_goal_heading: bool,
    ) -> None:
        self.cfg, self.vehicle, self.world, self.link = cfg, vehicle, world, link
        self.plans = plans
        self.goal, self.fix_goal_heading = goal, fix_goal_heading
        self._asked: Asked | None = None  # what the plan being made was asked for
        self._plan_lags: deque[float] = deque(maxlen=PLAN_LAGS_KEPT)  # how long plans took

    @property
    def clearance_margin_m(self) -> float:
        """The margin a plan made now aims beyond the required clearance (m): the configured
        one widened by the loop's measured delay (a tube as wide as the prediction's drift
        grows) and by the current the estimate may yet settle to, to the centimetre."""
        extra = self.cfg.clearance_margin_per_delay_s * self.link.loop_delay_s
        current = math.hypot(*self.link.doubted_current_mps)
        extra += self.cfg.clearance_margin_per_current_s * current
        return round(self.cfg.clearance_margin_m + extra, 2)

    @property
    def ground_turn_radius_m(self) -> float:
        """The tightest turn a plan made now may ask of the vehicle over ground (m): R_min of
        eqs. (19)-(20) is the hull's, through the water. Its heading turns at most v / R_min
        while the current carries it on; in a following current of c, the track over ground
        turns at that rate at speed v + c, and a crab into a cross current asks the same: a
        bend of radius R_min (1 + |c| / v)^2 over ground is what the hull can hold, at
        cruise speed, with the current from any side; c is the current the estimate may yet
        settle to (link.py `doubted_current`)."""
        c = math.hypot(*self.link.doubted_current_mps)
        factor = 1.0 + c / self.vehicle.cruise_speed_mps
        return self.vehicle.turn_radius_min_m * factor * factor

    def _pace(self, here: Pose2D) -> float:
        """Speed over ground per speed through the water for a vehicle at cruise speed heading
        from `here` for the goal and crabbing into the believed current (PlanRequest.pace):
        a following current brings it past a moving obstacle sooner than its speed through
        the water says, a head current later (at least a fifth of it)."""
        cx, cy = self.link.model.current_mps
        if cx == 0.0 and cy == 0.0:
            return 1.0
        d = math.atan2(self.goal.y - here.y, self.goal.x - here.x)
        c_t = math.cos(d) * cx + math.sin(d) * cy
        c_n = -math.sin(d) * cx + math.cos(d) * cy
        v = self.vehicle.cruise_speed_mps
        across = min(abs(c_n), v)
        return max(0.2, (math.sqrt(v * v - across * across) + c_t) / v)

    def _plan_config(self) -> PlannerConfig:
        """The planner's config with the clearance margin in force now."""
        margin = self.clearance_margin_m
        if margin == self.cfg.clearance_margin_m:
            return self.cfg
        return replace(self.cfg, clearance_margin_m=margin)

    def start_of(
        self,
        t_plan: float,
        here: Pose2D,
        pred: Prediction,
        why: str,
        ref: PathArcReference | None,
        s_now: float,
    ) -> tuple[float, Pose2D, tuple[float, float]]:
        """When and where a plan asked now should start, and the vehicle's twist (v, w) then:
        where the vehicle will be on the path in force `ref` (last at s_now) once the plan is
        made, as long as the last plans took (the median of the last PLAN_LAGS_KEPT). A plan
        of seconds made from where the vehicle was when it was asked starts metres behind it
        by the time it is in force, and the vehicle replans at once for the deviation. In
        virtual time a plan is made within its step: t_plan and `here`.
        Only for a vehicle on its path (not off it, nor after a silence) and at most up to the
        stop short of a conflict (PathArcReference.stop_s)."""
        lag = min(median(self._plan_lags), PLAN_AHEAD_MAX_S) if self._plan_lags else 0.0
        v = pred.at_effect[3]
        if lag <= 0.0 or ref is None or why not in _ALONG_THE_PATH:
            return t_plan, here, (v, pred.at_effect[4])
        s_here = ref.closest_s(here.x, here.y, s_now)
        s_then = min(s_here + max(v, 0.0) * lag, ref.stop_s, ref.length)
        x, y = ref.point_at_s(s_then)
        # there it turns as the path in force does, its hull crabbed into the current (`ask`
        # takes a hull's heading: its course is then the path's)
        twist = (v, v * ref.curvature_at_s(s_then))
        course = ref.heading_at_s(s_then)
        theta = course + crab_angle(self.link.model.current_mps, course, v)
        return t_plan + lag, Pose2D(x=x, y=y, theta=theta), twist

    def ask(
        self,
        t: float,
        t_plan: float,
        here: Pose2D,
        twist: tuple[float, float],
        obstacles: Obstacles,
        why: str,
        *,
        controller: Controller,
        aside: PlanResult | None,
    ) -> None:
        """Start (at step t) a plan from `here`, the pose at t_plan, where the vehicle moves
        with `twist` (v, w) (the obstacles as they are then); flown by `controller` before it
        is adopted (rollout.py); `aside`: the way aside in force, if any (evade.py).

        The plan is over ground, so it leaves along the vehicle's course, not its hull's
        heading: in a cross current the two differ by the crab angle (11 deg at 0.3 m/s
        across 1.5 m/s), and a path leaving along the heading had the controllers, which
        steer the course, start it that far off (they swung wide after every replan) and
        made "no curve leaves along the heading" recoveries near obstacles. The rollout
        starts from the hull's own state."""
        current = self.link.model.current_mps
        course = course_over_ground(here.theta, twist[0], controller.sway, current)
        req = PlanRequest(
            start=replace(here, theta=course),
            goal=self.goal,
            area=self.world.area,
            obstacles=obstacles,
            vehicle_radius_m=self.vehicle.radius_m,
            r_min_m=self.ground_turn_radius_m,
            v_ref_mps=self.vehicle.cruise_speed_mps,
            fix_goal_heading=self.fix_goal_heading,
            pace=self._pace(here),
            goal_tolerance_m=self.world.goal_tolerance_m,
        )
        cfg = self._plan_config()
        self._asked = Asked(
            t_plan=t_plan,
            obstacles=obstacles,
            why=why,
            asked_t=t,
            current=current,
            pace=req.pace,
        )
        # a copy now: the plan may be made beside the steps, which go on using it; it flies
        # in the current believed now (the live controller learns it only when it follows a
        # path: before the first one, or after a NO_PATH, its own is stale)
        flown = copy.deepcopy(controller)
        flown.current = current
        flight = RolloutInputs(
            controller=flown,
            model=self.link.model,
            doubt=self.link.model.with_current(*self.link.doubted_current_mps),
            step_s=self.cfg.period_s,
            start=(here.x, here.y, here.theta, *twist),
            start_std_m=self.link.position_std_m,
            t0=t_plan,
        )
        r_water = self.vehicle.turn_radius_min_m
        ask = PlanAsk(req=req, r_water_m=r_water, cfg=cfg, rollout=flight, aside=aside)
        self.plans.start(lambda: plan_clear_of_contact(ask))

    def done(self, t: float) -> Asked:
        """A plan is made (step t): what it was asked for, its lag counted (and told, if
        slow)."""
        asked, self._asked = self._asked, None
        assert asked is not None
        self._plan_lags.append(t - asked.asked_t)  # 0 in virtual time: made within the step
        if t - asked.asked_t > SLOW_PLAN_S:  # realtime only: in virtual time a plan is at once
            log.info(
                "t=%.2f s: a plan asked at t=%.2f s (%s, for t=%.2f s) took until now: the "
                "path in force was followed meanwhile, unchecked (short of its conflict, if "
                "infeasible)",
                t,
                asked.asked_t,
                asked.why,
                asked.t_plan,
            )
        return asked
