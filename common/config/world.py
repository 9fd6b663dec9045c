"""World configuration: area, start/goal, static and moving obstacles (paper §2, §3.1, §4),
and the ocean current (common/config/current.py).

Checks that need the geometry model (simple polygons, start and goal outside every obstacle)
run after loading, in common.world.check; this package does not import common.world.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from common.config.current import CurrentConfig
from common.config.errors import ConfigValueError

MovingKind = Literal["line", "waypoints", "sinusoid"]


@dataclass(frozen=True, kw_only=True)
class AreaConfig:
    """The rectangular operating area X of the boundary constraint (paper: 100 x 40 m)."""

    x_min_m: float = 0.0
    x_max_m: float = 100.0
    y_min_m: float = 0.0
    y_max_m: float = 40.0

    def __post_init__(self) -> None:
        for name in ("x_min_m", "x_max_m", "y_min_m", "y_max_m"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(
                    name, f"{getattr(self, name)!r} is not finite, expected a number"
                )
        if self.x_min_m >= self.x_max_m:
            raise ConfigValueError("x_min_m", f"{self.x_min_m} must be < x_max_m ({self.x_max_m})")
        if self.y_min_m >= self.y_max_m:
            raise ConfigValueError("y_min_m", f"{self.y_min_m} must be < y_max_m ({self.y_max_m})")

    def contains(self, x: float, y: float) -> bool:
        return self.x_min_m <= x <= self.x_max_m and self.y_min_m <= y <= self.y_max_m


@dataclass(frozen=True, kw_only=True)
class PoseConfig:
    """A planar pose (x, y, heading theta measured from the x axis, counter-clockwise), and for
    a start the speed through the water the vehicle has there."""

    x_m: float
    y_m: float
    theta_rad: float = 0.0
    # a start under way: the vehicle enters the area at this speed, heading theta_rad (an AUV
    # reaches its survey area after its dive), and holds it until its first command; 0: at rest
    speed_mps: float = 0.0

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "theta_rad"):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(
                    name, f"{getattr(self, name)!r} is not finite, expected a number"
                )
        if not (math.isfinite(self.speed_mps) and self.speed_mps >= 0.0):
            raise ConfigValueError("speed_mps", f"{self.speed_mps!r}, expected a speed >= 0")


@dataclass(frozen=True, kw_only=True)
class CircleObstacleConfig:
    """A static circular obstacle."""

    id: int
    x_m: float
    y_m: float
    radius_m: float

    def __post_init__(self) -> None:
        _check_id(self.id)
        if not self.radius_m > 0.0:
            raise ConfigValueError("radius_m", f"{self.radius_m!r} must be > 0")


@dataclass(frozen=True, kw_only=True)
class PolygonObstacleConfig:
    """A static simple polygon obstacle; vertices flat (x0, y0, x1, y1, ...), any winding."""

    id: int
    vertices_m: tuple[float, ...]

    def __post_init__(self) -> None:
        _check_id(self.id)
        if len(self.vertices_m) % 2 or len(self.vertices_m) < 6:
            raise ConfigValueError(
                "vertices_m",
                f"{len(self.vertices_m)} numbers, expected an even count >= 6 "
                "(at least three x, y vertices)",
            )
        if not all(math.isfinite(v) for v in self.vertices_m):
            raise ConfigValueError("vertices_m", "every coordinate must be finite")
        # Simplicity and non-zero area are geometry: common.world.check checks them after loading.


@dataclass(frozen=True, kw_only=True)
class MovingObstacleConfig:
    """A moving circular obstacle whose centre follows alpha_k(t) (paper §2).

    kind "line": alpha(t) = p0 + v t (constant velocity, forever).
    kind "waypoints": loops p0 -> waypoints_m[0] -> ... -> back to p0 at speed_mps.
    kind "sinusoid": alpha(t) = p0 + v t + A sin(2 pi f t + phase) n, n the left normal of v
    (a crossing obstacle weaving across its direction of travel).
    """

    id: int
    kind: MovingKind = "line"
    radius_m: float = 1.0
    x0_m: float
    y0_m: float
    vx_mps: float = 0.0  # line, sinusoid
    vy_mps: float = 0.0  # line, sinusoid
    waypoints_m: tuple[float, ...] = ()  # waypoints: further vertices of the loop, flat x, y
    speed_mps: float = 0.0  # waypoints
    amplitude_m: float = 0.0  # sinusoid
    frequency_hz: float = 0.0  # sinusoid
    phase_rad: float = 0.0  # sinusoid

    def __post_init__(self) -> None:
        _check_id(self.id)
        if self.kind not in ("line", "waypoints", "sinusoid"):
            raise ConfigValueError(
                "kind", f"{self.kind!r}, expected 'line', 'waypoints' or 'sinusoid'"
            )
        if not self.radius_m > 0.0:
            raise ConfigValueError("radius_m", f"{self.radius_m!r} must be > 0")
        for name in (
            "x0_m",
            "y0_m",
            "vx_mps",
            "vy_mps",
            "speed_mps",
            "amplitude_m",
            "frequency_hz",
            "phase_rad",
        ):
            if not math.isfinite(getattr(self, name)):
                raise ConfigValueError(name, f"{getattr(self, name)!r}, expected a finite number")
        if not all(math.isfinite(v) for v in self.waypoints_m):
            raise ConfigValueError("waypoints_m", "every coordinate must be finite")
        if self.kind == "waypoints":
            if len(self.waypoints_m) % 2 or not self.waypoints_m:
                raise ConfigValueError(
                    "waypoints_m", "expected an even, non-empty list of x, y (the loop after p0)"
                )
            if not self.speed_mps > 0.0:
                raise ConfigValueError(
                    "speed_mps", f"{self.speed_mps!r} must be > 0 for kind 'waypoints'"
                )
            pts = ((self.x0_m, self.y0_m), *_pairs(self.waypoints_m))
            loop = sum(math.dist(a, b) for a, b in zip(pts, pts[1:] + pts[:1], strict=True))
            if loop < 1e-9:
                raise ConfigValueError("waypoints_m", "the loop has zero length")
        if self.kind == "sinusoid":
            if math.hypot(self.vx_mps, self.vy_mps) <= 0.0:
                raise ConfigValueError(
                    "vx_mps", "a 'sinusoid' needs a non-zero drift velocity (vx, vy)"
                )
            for name in ("amplitude_m", "frequency_hz"):
                if not getattr(self, name) >= 0.0:
                    raise ConfigValueError(name, f"{getattr(self, name)!r} must be >= 0")


@dataclass(frozen=True, kw_only=True)
class GoalConfig:
    """Where a vehicle must arrive, and its heading there (eq. (10)'s theta_f) if given: without
    `theta_rad` the heading at the goal is free (the path arrives along its own last leg)
    rather than silently east, which made a vehicle coming from the east loop round near the
    edge of the area to arrive facing it."""

    x_m: float
    y_m: float
    theta_rad: float | None = None

    def __post_init__(self) -> None:
        for name in ("x_m", "y_m", "theta_rad"):
            value = getattr(self, name)
            if value is not None and not math.isfinite(value):
                raise ConfigValueError(name, f"{value!r} is not finite, expected a number")


@dataclass(frozen=True, kw_only=True)
class WorldConfig:
    """The scenario's world: area, start/goal poses, obstacles (ids unique over all), current.

    The current (`[world.current]`) is the water every vehicle of the run moves in."""

    area: AreaConfig = field(default_factory=AreaConfig)
    start: PoseConfig = field(default_factory=lambda: PoseConfig(x_m=5.0, y_m=20.0))
    goal: GoalConfig = field(default_factory=lambda: GoalConfig(x_m=95.0, y_m=20.0))
    goal_tolerance_m: float = 1.0
    circles: tuple[CircleObstacleConfig, ...] = ()
    polygons: tuple[PolygonObstacleConfig, ...] = ()
    moving: tuple[MovingObstacleConfig, ...] = ()
    current: CurrentConfig = field(default_factory=CurrentConfig)  # [world.current]

    def __post_init__(self) -> None:
        if not self.goal_tolerance_m > 0.0:
            raise ConfigValueError("goal_tolerance_m", f"{self.goal_tolerance_m!r} must be > 0")
        for name, pose in (("start", self.start), ("goal", self.goal)):
            if not self.area.contains(pose.x_m, pose.y_m):
                raise ConfigValueError(name, f"({pose.x_m}, {pose.y_m}) lies outside the area")
        seen: set[int] = set()
        for group, ids in (
            ("circles", [c.id for c in self.circles]),
            ("polygons", [p.id for p in self.polygons]),
            ("moving", [m.id for m in self.moving]),
        ):
            for i, oid in enumerate(ids):
                if oid in seen:
                    raise ConfigValueError(
                        (group, i, "id"),
                        f"obstacle id {oid} is used twice, expected ids unique over "
                        "circles, polygons and moving",
                    )
                seen.add(oid)
        for i, c in enumerate(self.circles):
            if not self.area.contains(c.x_m, c.y_m):
                raise ConfigValueError(
                    ("circles", i), f"centre ({c.x_m}, {c.y_m}) lies outside the area"
                )
        for i, p in enumerate(self.polygons):
            xs, ys = p.vertices_m[::2], p.vertices_m[1::2]
            if not all(self.area.contains(x, y) for x, y in zip(xs, ys, strict=True)):
                raise ConfigValueError(
                    ("polygons", i, "vertices_m"), "a vertex lies outside the area"
                )
        for i, m in enumerate(self.moving):
            pts = ((m.x0_m, m.y0_m), *_pairs(m.waypoints_m))
            if not all(self.area.contains(x, y) for x, y in pts):
                raise ConfigValueError(
                    ("moving", i), "its start or a waypoint lies outside the area"
                )
        # Whether start and goal lie inside an obstacle is geometry: common.world.check.


def _check_id(i: int) -> None:
    if not isinstance(i, int) or isinstance(i, bool) or i < 0:
        raise ConfigValueError("id", f"{i!r} must be an integer >= 0")


def _pairs(flat: tuple[float, ...]) -> tuple[tuple[float, float], ...]:
    return tuple(zip(flat[::2], flat[1::2], strict=True))
