"""When to replan: a small pure policy over the current path, the vehicle pose and obstacles.

Events (any one triggers a replan, but never sooner than min_replan_interval_s after the
last replan, so noisy tracks cannot make the planner chatter):
  no_path       there is no usable path yet (none planned, or the last attempt failed);
  aside         the path in force only steps aside, short of the goal (evade.py): try the
                goal again;
  goal_changed  the goal moved;
  deviation     the vehicle is farther than deviation_threshold_m from its path;
  infeasible    the rest of the path violates eq. (12)-(13): some obstacle (static, or moving
                at the time the vehicle will pass) is closer than r + rho0 (static ones are
                not counted over the plan's escape_m, which it may pass closer: leaving the
                margin, or contact, is what that stretch is for); or the path in force was
                kept cut short of such a conflict (decline.py `keeps_safer_path`);
  corridor      a tracked moving obstacle the current plan did not account for is predicted
                to come within corridor_halfwidth_m of the path ahead when the vehicle passes;
  cruise        the path in force was made for less than cruise speed (rollout.py: a bend no
                faster flight held clear of rho0) and the vehicle is past its slow_until_m;
  current       the estimated current differs by more than current_change_mps from the one
                the path in force was flown in (rollout.py) before it was adopted.
The core adds one event of its own, ahead of these and of the interval:
  resumed       it sent no command for longer than the vehicle's hold_after_s (and
                max_estimate_age_s): it was stopped, or its uplink was out, while the vehicle
                held off the plan, so the plan and its controller's state are stale.
A replan should start from the vehicle's current pose (see `replan_request`).
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from common.config.planner import PlannerConfig
from common.world.geometry import Box, FloatArray
from services.planner.geometry.clearance import StaticField
from services.planner.plan import PlanRequest, PlanResult
from services.planner.result import Obstacles, Pose2D
from services.planner.safety.intent import IntentObstacle

ReplanReason = Literal[
    "",
    "no_path",
    "goal_changed",
    "deviation",
    "infeasible",
    "corridor",
    "cruise",
    "aside",
    "resumed",
    "current",
]


@dataclass(frozen=True, kw_only=True)
class ReplanDecision:
    """Whether to replan now, the event that asks for it, and a human-readable detail.

    `conflict_s`: for "infeasible", the arc length along the current path (from its start)
    of the first sample ahead that breaks eq. (12)-(13); inf otherwise."""

    replan: bool
    reason: ReplanReason = ""
    detail: str = ""
    conflict_s: float = math.inf


def replan_request(base: PlanRequest, pose: Pose2D, obstacles: Obstacles) -> PlanRequest:
    """The same problem, planned from the vehicle's current pose with the current obstacles."""
    return dataclasses.replace(base, start=pose, obstacles=obstacles)


class ReplanPolicy:
    """Keeps the current path (dense samples with arc length) and decides on replans."""

    def __init__(
        self,
        cfg: PlannerConfig,
        *,
        vehicle_radius_m: float,
        v_ref_mps: float,
        n_samples: int = 400,
    ) -> None:
        self.cfg = cfg
        self.r = vehicle_radius_m
        self.cruise = v_ref_mps
        self.v_ref = v_ref_mps  # the speed of the path in force (a slower plan's: rollout.py)
        self.n_samples = n_samples
        self.pts: FloatArray | None = None  # (K, 2) samples of the current path
        self.s: FloatArray = np.zeros(0)  # (K,) arc length of each sample
        self.goal: Pose2D | None = None
        self.known_ids: frozenset[int] = frozenset()  # tracks the current plan accounted for
        self.last_replan_t: float | None = None
        self.s_now = 0.0  # progress along the path (m), monotone
        self.escape_m = 0.0  # the current plan's first escape_m may pass static obstacles closer
        self.slow_until_m = math.inf  # a slower plan's arc length past which cruise resumes
        self.short_of_goal = False  # the path in force steps aside, short of the goal
        self.cut_short = False  # it was kept, cut short of a conflict ahead (on_kept)
        self.current: tuple[float, float] = (0.0, 0.0)  # the path in force was flown in it
        self.pace = 1.0  # speed over ground per speed through the water along it
        self.last_check_t: float | None = None
        # Static obstacles do not move: their distance to each path sample is worked out once
        # per (path, static obstacle set) and sliced at every check, not recomputed at every
        # step (docs/notes/planner-replan-static-distances-cached.md).
        self._static_for: tuple[object, object] | None = None
        self._static_d: FloatArray = np.zeros(0)

    # --- state updates -------------------------------------------------------------------
    def on_planned(
        self,
        t: float,
        result: PlanResult,
        goal: Pose2D,
        obstacles: Obstacles,
        current: tuple[float, float] = (0.0, 0.0),
        pace: float = 1.0,
    ) -> None:
        """Record a replan attempt at time t (its result may be NO_PATH), flown in `current`
        at `pace` (PlanRequest.pace)."""
        self.last_replan_t = t
        self.current = current
        self.pace = pace
        self.goal = goal
        self.s_now = 0.0
        self.last_check_t = t
        self.escape_m = result.escape_m
        self.v_ref = self.cruise if result.v_ref_mps is None else result.v_ref_mps
        self.slow_until_m = result.slow_until_m
        self.short_of_goal = result.short_of_goal
        self.cut_short = False
        if not result.ok:
            self.pts = None
            return
        curve = result.curve()
        u = np.linspace(curve.u_min, curve.u_max, self.n_samples)
        self.pts = curve.evaluate(u, n_ders=0)[0]
        self.s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(self.pts, axis=0).T))])
        self._static_for = None
        gap, ids = _least_gaps(self._sample_gaps(obstacles, 0, 0.0), obstacles)
        self.known_ids = frozenset(ids[gap < self.cfg.corridor_halfwidth_m].tolist())

    def on_kept(self, t: float, obstacles: Obstacles, *, cut_short: bool = False) -> None:
        """A replan at time t was declined and the current path kept (decline.py): the moving
        obstacles it was asked with count as accounted for, and the interval runs from t.
        `cut_short`: it was kept stopping short of a conflict, so a plan is asked again at
        the next interval even once the conflict has gone (else it would stop there)."""
        self.last_replan_t = t
        self.known_ids |= {o.id for o in obstacles.moving}
        self.cut_short = self.cut_short or cut_short

    @property
    def remaining_m(self) -> float:
        """Arc length of the path in force ahead of the vehicle's progress (0 without one)."""
        return float(self.s[-1]) - self.s_now if self.pts is not None else 0.0

    # --- the decision --------------------------------------------------------------------
    def check(
        self,
        t: float,
        pose: Pose2D,
        goal: Pose2D,
        obstacles: Obstacles,
        current: tuple[float, float] = (0.0, 0.0),
    ) -> ReplanDecision:
        """Decide at time t; obstacles are given by their state at time t, `current` is the
        estimated current (m/s)."""
        if (
            self.last_replan_t is not None
            and t - self.last_replan_t < self.cfg.min_replan_interval_s
        ):
            return ReplanDecision(replan=False, detail="within the minimum replan interval")
        if self.pts is None:
            return ReplanDecision(replan=True, reason="no_path", detail="no usable path")
        if self.short_of_goal:
            self._progress(t, pose)  # remaining_m: whether the way aside has run out
            return ReplanDecision(
                replan=True,
                reason="aside",
                detail="the path in force steps aside, short of the goal",
            )
        if self.goal is None or _moved(self.goal, goal):
            return ReplanDecision(replan=True, reason="goal_changed", detail="the goal moved")
        i_now, dev = self._progress(t, pose)
        if dev > self.cfg.deviation_threshold_m:
            return ReplanDecision(
                replan=True,
                reason="deviation",
                detail=f"{dev:.2f} m from the path > {self.cfg.deviation_threshold_m:.2f} m",
            )
        conflict = self._static_conflict(obstacles, i_now)
        if conflict is None:
            conflict = self._moving_conflict(obstacles, i_now)
        if conflict is not None:
            return conflict
        if self.cut_short:
            return ReplanDecision(
                replan=True,
                reason="infeasible",
                detail="the path in force stops short of a conflict no longer ahead",
            )
        change = math.hypot(current[0] - self.current[0], current[1] - self.current[1])
        if change > self.cfg.current_change_mps:
            return ReplanDecision(
                replan=True,
                reason="current",
                detail=f"the current changed by {change:.2f} m/s since the path was flown",
            )
        if self.v_ref < self.cruise and self.s_now >= self.slow_until_m:
            return ReplanDecision(
                replan=True,
                reason="cruise",
                detail=f"{self.s_now:.1f} m along a path made for {self.v_ref:.2f} m/s, past "
                f"where it was slowed: back to {self.cruise:.2f} m/s",
            )
        return ReplanDecision(replan=False)

    # --- helpers -------------------------------------------------------------------------
    def _static_conflict(self, obstacles: Obstacles, i_now: int) -> ReplanDecision | None:
        """A replan for a static obstacle within rho0 of the path ahead of sample i_now."""
        assert self.pts is not None
        d_req = self.r + self.cfg.rho0_m
        ahead = self.pts[i_now:]
        d = self._static_distance(obstacles)[i_now:]
        if self.escape_m > 0.0 and len(d):  # the plan checked that stretch against them itself
            d = np.where(self.s[i_now:] < self.escape_m, np.inf, d)
        if len(d):
            j = int(np.argmin(d))
            if d[j] < d_req - 1e-6:
                return ReplanDecision(
                    replan=True,
                    reason="infeasible",
                    detail=f"static obstacle {d[j] - self.r:.2f} m from the path ahead "
                    f"at ({ahead[j, 0]:.1f}, {ahead[j, 1]:.1f}) < rho0",
                    conflict_s=float(self.s[i_now + int(np.argmax(d < d_req - 1e-6))]),
                )
        return None

    def _moving_conflict(self, obstacles: Obstacles, i_now: int) -> ReplanDecision | None:
        """A replan for a moving obstacle predicted within rho0 of the path ahead of sample
        i_now, or a new one within the corridor."""
        per_sample = self._sample_gaps(obstacles, i_now, self.s_now)
        gap, ids = _least_gaps(per_sample, obstacles)
        if len(gap):
            j = int(np.argmin(gap))
            if gap[j] < self.cfg.rho0_m - 1e-6:
                # the first sample ahead where any of them comes within rho0
                bad = np.logical_or.reduce([g < self.cfg.rho0_m - 1e-6 for g in per_sample])
                return ReplanDecision(
                    replan=True,
                    reason="infeasible",
                    detail=f"moving obstacle {ids[j]} predicted {gap[j]:.2f} m from the path",
                    conflict_s=float(self.s[i_now + int(np.argmax(bad))]),
                )
            new = [k for k in range(len(ids)) if ids[k] not in self.known_ids]
            hit = [k for k in new if gap[k] < self.cfg.corridor_halfwidth_m]
            if hit:
                k = min(hit, key=lambda q: gap[q])
                return ReplanDecision(
                    replan=True,
                    reason="corridor",
                    detail=f"moving obstacle {ids[k]} predicted {gap[k]:.2f} m from the path",
                )
        return None

    def _static_distance(self, obstacles: Obstacles) -> FloatArray:
        """Distance from every sample of the path to the nearest static obstacle (empty array
        when there are none), cached while the path and the static obstacles stay the same."""
        assert self.pts is not None
        key = (obstacles.circles, obstacles.polygons)
        if self._static_for is None or self._static_for != key:
            static = StaticField.build(obstacles.circles, obstacles.polygons)
            self._static_d = np.zeros(0) if static.empty else static.distance(self.pts)[0]
            self._static_for = key
        return self._static_d

    def _progress(self, t: float, pose: Pose2D) -> tuple[int, float]:
        """Nearest sample in a window ahead of the last progress, and the distance to it."""
        assert self.pts is not None
        dt = 0.0 if self.last_check_t is None else max(t - self.last_check_t, 0.0)
        self.last_check_t = t
        lo = self.s_now - 2.0
        hi = self.s_now + 2.0 * self.v_ref * dt + 10.0
        # the samples with lo <= s <= hi: a slice, for s (a cumulative sum of lengths) never
        # decreases
        i0 = int(np.searchsorted(self.s, lo, side="left"))
        i1 = int(np.searchsorted(self.s, hi, side="right"))
        d = np.hypot(self.pts[i0:i1, 0] - pose.x, self.pts[i0:i1, 1] - pose.y)
        j = int(np.argmin(d))
        k = i0 + j
        self.s_now = max(self.s_now, float(self.s[k]))
        dev = float(d[j])
        if k == 0:
            tx, ty = self.pts[1] - self.pts[0]
            dev = deviation_near_start(pose, (self.pts[0, 0], self.pts[0, 1]), (tx, ty), dev)
        return k, dev

    def _sample_gaps(self, obstacles: Obstacles, i_now: int, s_now: float) -> list[FloatArray]:
        """Per moving obstacle, the hull-to-surface gap at every path sample ahead (eq. 12-13);
        none without a path."""
        if self.pts is None:
            return []
        ahead = self.pts[i_now:]
        tau = (self.s[i_now:] - s_now) / (self.v_ref * self.pace)
        # a gap is only ever compared with rho0 and the corridor: another vehicle's route
        # farther than both from the path ahead is that far at every sample (its gap bound
        # stands for its gaps; a fleet's vehicles are mostly far from each other's paths)
        far = max(self.cfg.rho0_m, self.cfg.corridor_halfwidth_m)
        box: Box | None = None  # the path ahead's, once a route asks for it
        gaps = []
        for o in obstacles.moving:
            if len(ahead) and isinstance(o, IntentObstacle):
                if box is None:
                    box = Box.of(ahead[:, 0], ahead[:, 1])
                least = box.distance(o.route_box) - o.radius - self.r
                if least >= far:
                    gaps.append(np.full(len(ahead), least))
                    continue
            centres = o.centre_at(tau, self.cfg.accel_horizon_s)
            gaps.append(np.hypot(*(ahead - centres).T) - o.radius - self.r)
        return gaps


def _least_gaps(
    per_sample: list[FloatArray], obstacles: Obstacles
) -> tuple[FloatArray, np.ndarray]:
    """Per moving obstacle: the least of its per-sample gaps to the path ahead (eq. 12-13),
    and its id."""
    gaps = np.array([float(np.min(g)) for g in per_sample])
    return gaps, np.array([o.id for o in obstacles.moving], dtype=np.int64)


def _moved(a: Pose2D, b: Pose2D) -> bool:
    return math.hypot(a.x - b.x, a.y - b.y) > 1e-6 or abs(a.theta - b.theta) > 1e-9


def deviation_near_start(
    pose: Pose2D, start: tuple[float, float], tangent: tuple[float, float], dev: float
) -> float:
    """A vehicle's deviation from a path whose nearest point to it is the start (`dev`, the
    distance to it). Short of the start (a plan made for where the vehicle would be once it
    was made, done sooner than expected: core.py `_plan_start`) the vehicle is on its way to
    it: only how far it is to the side of the start's tangent deviates."""
    tx, ty = tangent
    ex, ey = pose.x - start[0], pose.y - start[1]
    norm = math.hypot(tx, ty)
    if norm > 0.0 and ex * tx + ey * ty < 0.0:
        return abs(ex * ty - ey * tx) / norm
    return dev
