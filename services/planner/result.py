"""The planner's request and result types: poses, obstacles to avoid, request, result."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Literal

import numpy as np

from common.config.vehicle import VehicleConfig
from common.config.world import (
    AreaConfig,
    CircleObstacleConfig,
    PolygonObstacleConfig,
    WorldConfig,
)
from common.world import ObstacleState, World
from common.world.geometry import FloatArray
from services.planner.geometry.nurbs_curve import NurbsCurve
from services.planner.geometry.planned_path import PlannedPath
from services.planner.reasons import Strategy

PlanStatus = Literal["OK", "NO_PATH"]


@dataclass(frozen=True, kw_only=True)
class Pose2D:
    """A planar pose: position (m) and heading theta (rad, from +x, counter-clockwise)."""

    x: float
    y: float
    theta: float


@dataclass(frozen=True, kw_only=True)
class Obstacles:
    """Everything one plan avoids: the chart's static obstacles, moving ones at plan time t = 0.

    The world's own types: static circles and polygons as in the scenario, moving obstacles
    as `ObstacleState` (predicted with `ObstacleState.centre_at`).
    """

    circles: tuple[CircleObstacleConfig, ...] = ()
    polygons: tuple[PolygonObstacleConfig, ...] = ()
    moving: tuple[ObstacleState, ...] = ()


@dataclass(frozen=True, kw_only=True)
class PlanRequest:
    """One planning problem. Moving obstacles are given by their state at plan time t = 0."""

    start: Pose2D
    goal: Pose2D
    area: AreaConfig = field(default_factory=AreaConfig)
    obstacles: Obstacles = field(default_factory=Obstacles)
    vehicle_radius_m: float  # the vehicle config's radius_m
    r_min_m: float = 2.0  # minimum turning radius R_min (eq. (19)-(20))
    v_ref_mps: float = 1.5  # cruise speed through the water
    fix_goal_heading: bool = True  # eq. (10): also impose theta_f at the goal
    # speed over ground per speed through the water on the way to the goal: 1 in still
    # water; in a current, how much faster (or slower) the vehicle passes along its path
    pace: float = 1.0
    # a plan to the goal is flown to within this of it (m; rollout.py); 0: not checked
    goal_tolerance_m: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.goal_tolerance_m) and self.goal_tolerance_m >= 0.0):
            raise ValueError(
                f"goal_tolerance_m: {self.goal_tolerance_m!r} is invalid, expected >= 0"
            )
        for name in ("vehicle_radius_m", "r_min_m", "v_ref_mps", "pace"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0.0):
                raise ValueError(f"{name}: {v!r} is invalid, expected a finite value > 0")

    @property
    def pace_mps(self) -> float:
        """The speed over ground that converts arc length to passing time, eq. (13) (m/s):
        moving obstacles are met where they are at t = s / pace_mps."""
        return self.v_ref_mps * self.pace

    @classmethod
    def across(
        cls,
        world: WorldConfig,
        vehicle: VehicleConfig,
        *,
        start: Pose2D | None = None,
        obstacles: Obstacles | None = None,
    ) -> PlanRequest:
        """A plan across a scenario's world for its vehicle (radius, R_min, cruise speed):
        from `start` (the world's own by default) to the world's goal, among `obstacles` (the
        world's by default: its chart, and the moving ones where they are at t = 0)."""
        if obstacles is None:
            moving = tuple(o for o in World(world).obstacles_at(0.0) if o.moving)
            obstacles = Obstacles(circles=world.circles, polygons=world.polygons, moving=moving)
        w0 = world.start
        goal, fixed = goal_of(world)
        return cls(
            start=start or Pose2D(x=w0.x_m, y=w0.y_m, theta=w0.theta_rad),
            goal=goal,
            area=world.area,
            obstacles=obstacles,
            vehicle_radius_m=vehicle.radius_m,
            r_min_m=vehicle.turn_radius_min_m,
            v_ref_mps=vehicle.cruise_speed_mps,
            fix_goal_heading=fixed,
        )


def goal_of(world: WorldConfig) -> tuple[Pose2D, bool]:
    """The world's goal pose, and whether its heading is imposed (eq. (10): only when the
    scenario gives one, GoalConfig; else the pose's theta is 0 and free)."""
    g = world.goal
    theta = 0.0 if g.theta_rad is None else g.theta_rad
    return Pose2D(x=g.x_m, y=g.y_m, theta=theta), g.theta_rad is not None


@dataclass(frozen=True, kw_only=True)
class PlanTiming:
    """Seconds spent per stage (all zero when no clock was handed to plan_path)."""

    costmap_s: float = 0.0
    search_s: float = 0.0  # graph search and line-of-sight pruning
    fit_s: float = 0.0  # initial fit and refinement rounds
    check_s: float = 0.0  # dense final checks
    total_s: float = 0.0


@dataclass(frozen=True, kw_only=True, eq=False)
class PlanResult:
    """A planned NURBS path (status OK) or NO_PATH with its reason, and its reason codes: the
    strategy that made it (for a NO_PATH, why none) and those rejected before (reasons.py)."""

    status: PlanStatus
    reason: str
    strategy: Strategy
    rejected: tuple[Strategy, ...] = ()
    degree: int = 0
    control_points: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))  # (n, 2)
    weights: FloatArray = field(default_factory=lambda: np.zeros(0))
    knots: FloatArray = field(default_factory=lambda: np.zeros(0))
    grid_path: FloatArray = field(default_factory=lambda: np.zeros((0, 2)))  # pruned waypoints
    length_m: float = 0.0  # eq. (16)/(18) length of the curve
    f_l: float = 0.0  # L / straight-line start-goal distance
    max_curvature: float = 0.0  # 1/m over the dense samples; < 1/R_min when OK (eq. (20))
    min_clearance_m: float = 0.0  # hull-to-obstacle-surface minimum; >= rho0 when OK
    turn_penalty: float = 0.0  # eq. (19) f_R of the final curve
    rounds: int = 0  # refinement rounds used (over all search attempts)
    # the first escape_m of arc length may pass closer than r + rho0: a start inside the
    # margin leaves it within planner.escape_len_m; a start in contact first escapes it
    escape_m: float = 0.0
    # the heading change of the arc a recovery starts with (recover.py; > 0 to the left):
    # 0 when the curve leaves straight ahead
    turn_rad: float = 0.0
    # how far that recovery's way out goes below min(the start's clearance, rho0): into the
    # safety margin, or deeper into it (escape.py `deeper_m`); 0 when it keeps out
    margin_entered_m: float = 0.0
    # the speed the plan was made and flown for, when slower than the request's cruise speed
    # (rollout.py: a plan no faster flight kept rho0 on); None: the request's v_ref_mps
    v_ref_mps: float | None = None
    # a slower plan's arc length (from its start) past which the place it was slowed for lies
    # behind: there the replan policy asks for a plan at cruise speed again (replan.py)
    slow_until_m: float = math.inf
    # a way aside that stops short of the goal (evade.py: no plan reaches it, and holding is
    # in a moving obstacle's way); the replan policy tries the goal again at every interval
    short_of_goal: bool = False
    # a plan to a point along the searched route, no curve reaching the goal (partway.py)
    partway: bool = False
    # a plan adopted although its rollout falls short of the clearance it must keep (rollout.py:
    # none made again fared better): by how much at most (m), and when it first falls short (s
    # after its start); 0 and inf
    # for a plan whose rollout keeps it, or that was not flown
    flown_short_m: float = 0.0
    flown_short_at_s: float = math.inf
    timing: PlanTiming = field(default_factory=PlanTiming)
    # the plan's PlannedPath once built (`planned_path`), with the arrays it was built from:
    # a result made from this one by dataclasses.replace (coded, its reason or speed given)
    # shares it, so its flights and its adoption tabulate the curve once; one with other
    # arrays builds its own
    _path: list[tuple[tuple[int, FloatArray, FloatArray, FloatArray], PlannedPath]] = field(
        default_factory=list, compare=False, repr=False
    )
    # the curve's dense samples (3, m, 2), with the arrays they are of: the check that passed
    # it evaluated them (check.py `CurveCheck.samples`), and its PlannedPath's table is them
    _samples: list[tuple[tuple[int, FloatArray, FloatArray, FloatArray], FloatArray]] = field(
        default_factory=list, compare=False, repr=False
    )

    @property
    def ok(self) -> bool:
        return self.status == "OK"

    @property
    def tried(self) -> tuple[Strategy, ...]:
        """The strategies run up to this result: those rejected, then the one that made it
        (a NO_PATH's code says why none, and names no strategy)."""
        return (*self.rejected, self.strategy) if self.ok else self.rejected

    def coded(self, strategy: Strategy, rejected: tuple[Strategy, ...] = ()) -> PlanResult:
        """This result as made by `strategy`, after the strategies `rejected`."""
        return replace(self, strategy=strategy, rejected=rejected)

    def after(self, failed: str, note: str) -> PlanResult:
        """This result of a fallback, its reason told after the failure that led to it:
        "<failed>; <note>[: <its own reason>]"."""
        own = f": {self.reason}" if self.reason else ""
        return replace(self, reason=f"{failed}; {note}{own}")

    def curve(self) -> NurbsCurve:
        if not self.ok:
            raise ValueError(f"no curve: {self.reason}")
        return NurbsCurve(self.degree, self.control_points, self.weights, self.knots)

    def same_curve(self, other: PlanResult) -> bool:
        """Whether `other` carries this very curve (the same arrays: made from this result by
        dataclasses.replace, or this result itself)."""
        return _same_arrays(self._curve_of(), other._curve_of())

    def _curve_of(self) -> tuple[int, FloatArray, FloatArray, FloatArray]:
        return self.degree, self.control_points, self.weights, self.knots

    def planned_path(self) -> PlannedPath:
        """The curve with its arc-length table (an OK plan's), built once for the curve."""
        if self._path:
            of, built = self._path[0]
            if _same_arrays(of, self._curve_of()):
                return built
        samples = None
        if self._samples and _same_arrays(self._samples[0][0], self._curve_of()):
            samples = self._samples[0][1]
        built = PlannedPath(self.curve(), samples=samples)
        self._path[:] = [(self._curve_of(), built)]
        return built

    @staticmethod
    def of_curve(curve: NurbsCurve, samples: FloatArray | None = None, **fields: Any) -> PlanResult:
        """An OK plan of `curve`, with the rest of its fields as given; `samples`: the curve's
        dense samples its check evaluated (`_samples`), if any."""
        result = PlanResult(
            status="OK",
            degree=curve.degree,
            control_points=curve.ctrl,
            weights=curve.weights,
            knots=curve.knots,
            **fields,
        )
        if samples is not None:
            result._samples.append((result._curve_of(), samples))
        return result


def _same_arrays(
    a: tuple[int, FloatArray, FloatArray, FloatArray],
    b: tuple[int, FloatArray, FloatArray, FloatArray],
) -> bool:
    """Whether two (degree, control points, weights, knots) are the same degree and arrays."""
    return a[0] == b[0] and a[1] is b[1] and a[2] is b[2] and a[3] is b[3]
