"""The arc-length reference every tracking controller follows: a path whose methods take s.

The planner's NURBS path implements it (services/planner/shaping/path_arc_reference.py), as do the
analytic shapes of controllers/shapes.py.
"""

from __future__ import annotations

from typing import Protocol


class ArcLengthReference(Protocol):
    """A planar path parameterised by arc length s in [0, length], with a cruise speed.

    Headings are radians from the world x axis; curvature is signed (> 0 turning left,
    i.e. counter-clockwise). `closest_s` returns the arc length of the closest point; `s_hint`
    (the previous projection) lets an implementation stay on the current leg of a path that
    comes back near itself.
    """

    @property
    def length(self) -> float: ...

    @property
    def v_ref(self) -> float: ...

    def closest_s(self, x: float, y: float, s_hint: float | None) -> float: ...

    def point_at_s(self, s: float) -> tuple[float, float]: ...

    def heading_at_s(self, s: float) -> float: ...

    def curvature_at_s(self, s: float) -> float: ...
