"""Simple analytic references (straight line, circle, polyline) for tests and demos."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from common.scalar import clamp


@dataclass(frozen=True, kw_only=True)
class StraightLine:
    """The segment from (x0, y0) to (x1, y1)."""

    x0: float
    y0: float
    x1: float
    y1: float
    v_ref: float = 1.5

    @property
    def length(self) -> float:
        return math.hypot(self.x1 - self.x0, self.y1 - self.y0)

    def _unit(self) -> tuple[float, float]:
        n = self.length
        return (self.x1 - self.x0) / n, (self.y1 - self.y0) / n

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        ux, uy = self._unit()
        return clamp((x - self.x0) * ux + (y - self.y0) * uy, 0.0, self.length)

    def point_at_s(self, s: float) -> tuple[float, float]:
        ux, uy = self._unit()
        return self.x0 + s * ux, self.y0 + s * uy

    def heading_at_s(self, s: float) -> float:
        return math.atan2(self.y1 - self.y0, self.x1 - self.x0)

    def curvature_at_s(self, s: float) -> float:
        return 0.0


@dataclass(frozen=True, kw_only=True)
class Circle:
    """`turns` laps of a circle, from polar angle phase0, counter-clockwise if ccw."""

    cx: float
    cy: float
    radius: float
    phase0: float = 0.0
    ccw: bool = True
    turns: float = 3.0
    v_ref: float = 1.5

    @property
    def length(self) -> float:
        return 2.0 * math.pi * self.radius * self.turns

    @property
    def _sign(self) -> float:
        return 1.0 if self.ccw else -1.0

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        phase = math.atan2(y - self.cy, x - self.cx)
        base = self._sign * (phase - self.phase0) * self.radius
        lap = 2.0 * math.pi * self.radius
        hint = 0.0 if s_hint is None else s_hint
        # the unwrapped arc length closest to the hint (the previous projection)
        return clamp(base + lap * round((hint - base) / lap), 0.0, self.length)

    def point_at_s(self, s: float) -> tuple[float, float]:
        phase = self.phase0 + self._sign * s / self.radius
        return self.cx + self.radius * math.cos(phase), self.cy + self.radius * math.sin(phase)

    def heading_at_s(self, s: float) -> float:
        return self.phase0 + self._sign * (s / self.radius + 0.5 * math.pi)

    def curvature_at_s(self, s: float) -> float:
        return self._sign / self.radius


@dataclass(frozen=True, kw_only=True)
class Polyline:
    """Straight legs through the points (x0, y0, x1, y1, ...); curvature 0 on every leg."""

    points: tuple[float, ...]
    v_ref: float = 1.5
    window_m: float = 20.0  # with a hint, only legs within this arc length of it are searched
    _cum: tuple[float, ...] = field(init=False, repr=False)

    def __post_init__(self) -> None:
        if len(self.points) < 4 or len(self.points) % 2:
            raise ValueError("points: expected at least two (x, y) pairs, flat")
        cum = [0.0]
        for i in range(len(self.points) // 2 - 1):
            x0, y0, x1, y1 = self.points[2 * i : 2 * i + 4]
            cum.append(cum[-1] + math.hypot(x1 - x0, y1 - y0))
        object.__setattr__(self, "_cum", tuple(cum))

    @property
    def length(self) -> float:
        return self._cum[-1]

    def _leg(self, s: float) -> int:
        for i in range(len(self._cum) - 2):
            if s < self._cum[i + 1]:
                return i
        return len(self._cum) - 2

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float:
        best_s, best_d = 0.0, math.inf
        for i in range(len(self._cum) - 1):
            if s_hint is not None and (
                self._cum[i] > s_hint + self.window_m or self._cum[i + 1] < s_hint - self.window_m
            ):
                continue
            x0, y0, x1, y1 = self.points[2 * i : 2 * i + 4]
            seg = self._cum[i + 1] - self._cum[i]
            if seg <= 0.0:
                continue
            u = clamp(((x - x0) * (x1 - x0) + (y - y0) * (y1 - y0)) / (seg * seg), 0.0, 1.0)
            d = math.hypot(x0 + u * (x1 - x0) - x, y0 + u * (y1 - y0) - y)
            if d < best_d:
                best_s, best_d = self._cum[i] + u * seg, d
        return best_s

    def point_at_s(self, s: float) -> tuple[float, float]:
        s = clamp(s, 0.0, self.length)
        i = self._leg(s)
        x0, y0, x1, y1 = self.points[2 * i : 2 * i + 4]
        seg = self._cum[i + 1] - self._cum[i]
        u = 0.0 if seg <= 0.0 else (s - self._cum[i]) / seg
        return x0 + u * (x1 - x0), y0 + u * (y1 - y0)

    def heading_at_s(self, s: float) -> float:
        i = self._leg(clamp(s, 0.0, self.length))
        x0, y0, x1, y1 = self.points[2 * i : 2 * i + 4]
        return math.atan2(y1 - y0, x1 - x0)

    def curvature_at_s(self, s: float) -> float:
        return 0.0
