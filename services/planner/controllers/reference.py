"""The path interface every tracking controller reads (the planner's NURBS path implements it)."""

from __future__ import annotations

from typing import Protocol


class Reference(Protocol):
    """A planar path parameterised by arc length s in [0, length], with a cruise speed.

    Headings are radians from the world x axis; curvature is signed (> 0 turning left,
    i.e. counter-clockwise). `project` returns the arc length of the closest point; `s_hint`
    (the previous projection) lets an implementation stay on the current leg of a path that
    comes back near itself.
    """

    @property
    def length(self) -> float: ...

    @property
    def v_ref(self) -> float: ...

    def project(self, x: float, y: float, s_hint: float | None) -> float: ...

    def point(self, s: float) -> tuple[float, float]: ...

    def heading(self, s: float) -> float: ...

    def curvature(self, s: float) -> float: ...
