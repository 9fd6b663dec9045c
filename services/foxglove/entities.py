"""The scene entities of the Foxglove view: the chart, obstacles, tracks, the estimate, paths.

Each function draws one tidelink record (or the scenario's world) as SceneEntity objects in
the frame "world"; view.py decides when, and on which topic, they are sent.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from foxglove.messages import SceneEntity

from common.config.world import WorldConfig
from common.messages import ObstacleDetections, ObstacleTracks, StateEstimate
from common.world import ObstacleState
from services.foxglove.scene import (
    WORLD,
    arrow,
    circle_xy,
    disc,
    ellipse_xy,
    label,
    polyline,
    rgba,
    stamp,
)

GREY, DARK, RED = rgba("#9e9e9e", 0.9), rgba("#616161"), rgba("#c62828")
GREEN, PALE_GREEN, FAINT_GREEN = rgba("#2e7d32"), rgba("#a5d6a7", 0.7), rgba("#66bb6a", 0.35)
ORANGE, PURPLE, TEAL = rgba("#ef6c00"), rgba("#7b1fa2", 0.8), rgba("#00838f", 0.8)
PINK, MAGENTA = rgba("#d81b60", 0.35), rgba("#d81b60")
VELOCITY_HORIZON_S = 2.0  # a velocity arrow points where the motion leads in this time


def entity(eid: str, t: float, **primitives: Any) -> SceneEntity:
    """A SceneEntity in the world frame at mission time t (lives until replaced)."""
    return SceneEntity(timestamp=stamp(t), frame_id=WORLD, id=eid, **primitives)


def chart(w: WorldConfig, ends: bool = True) -> list[SceneEntity]:
    """The area's boundary, static obstacles and (`ends`) the start pose and the goal's
    tolerance circle."""
    a = w.area
    box = [(a.x_min_m, a.y_min_m), (a.x_max_m, a.y_min_m), (a.x_max_m, a.y_max_m)]
    box.append((a.x_min_m, a.y_max_m))
    out = [entity("area", 0.0, lines=[polyline(box, DARK, 0.15, closed=True)])]
    if ends:
        out += start_and_goal(w)
    for c in w.circles:
        out.append(
            entity(
                f"obstacle/{c.id}",
                0.0,
                cylinders=[disc(c.x_m, c.y_m, c.radius_m, GREY)],
                texts=[label(c.x_m, c.y_m, str(c.id), DARK)],
            )
        )
    for p in w.polygons:
        xy = np.asarray(p.vertices_m, dtype=np.float64).reshape(-1, 2)
        cx, cy = (float(v) for v in xy.mean(axis=0))
        out.append(
            entity(
                f"obstacle/{p.id}",
                0.0,
                lines=[polyline(xy, GREY, 0.4, closed=True)],
                texts=[label(cx, cy, str(p.id), DARK)],
            )
        )
    return out


def start_and_goal(w: WorldConfig, vehicle: str = "") -> list[SceneEntity]:
    """The start pose and the goal's tolerance circle (of fleet vehicle `vehicle`: named)."""
    st, g = w.start, w.goal
    goal_ring = circle_xy(g.x_m, g.y_m, w.goal_tolerance_m)
    heading = (math.cos(st.theta_rad), math.sin(st.theta_rad))
    tag = f"{vehicle}/" if vehicle else ""
    name = f"{vehicle} " if vehicle else ""
    return [
        entity(
            f"{tag}start",
            0.0,
            arrows=[arrow(st.x_m, st.y_m, *heading, VELOCITY_HORIZON_S, DARK)],
            texts=[label(st.x_m, st.y_m, f"{name}start", DARK)],
        ),
        entity(
            f"{tag}goal",
            0.0,
            lines=[polyline(goal_ring, RED, 0.12, closed=True)],
            texts=[label(g.x_m, g.y_m, f"{name}goal", RED)],
        ),
    ]


def moving(obstacles: Iterable[ObstacleState], t: float) -> list[SceneEntity]:
    """Moving obstacles where they truly are at t, with their velocity."""
    return [
        entity(
            f"moving/{o.id}",
            t,
            cylinders=[disc(o.x, o.y, o.radius, PURPLE)],
            arrows=[arrow(o.x, o.y, o.vx, o.vy, VELOCITY_HORIZON_S, PURPLE)],
            texts=[label(o.x, o.y, str(o.id), PURPLE)],
        )
        for o in obstacles
        if o.moving
    ]


def tracks(m: ObstacleTracks) -> list[SceneEntity]:
    """Each track: its radius, the 2-sigma hull (position ellipse grown by the radius: where
    the obstacle's edge may be), its velocity and id."""
    out = []
    for k in m.tracks:
        cov = np.asarray(k.covariance, dtype=np.float64).reshape(6, 6)  # x, y, vx, vy, ax, ay
        hull = ellipse_xy(k.x, k.y, cov[:2, :2], grow_m=k.radius)
        out.append(
            entity(
                f"track/{k.id}",
                m.stamp,
                cylinders=[disc(k.x, k.y, k.radius, PINK, height_m=0.2)],
                lines=[polyline(hull, MAGENTA, 0.06, closed=True)],
                arrows=[arrow(k.x, k.y, k.vx, k.vy, VELOCITY_HORIZON_S, MAGENTA)],
                texts=[label(k.x, k.y, f"track {k.id}", MAGENTA)],
            )
        )
    return out


def detections(m: ObstacleDetections) -> list[SceneEntity]:
    """One scan's detections as circles of their measured radius."""
    return [
        entity(
            f"detection/{d.id}",
            m.stamp,
            lines=[polyline(circle_xy(d.x, d.y, d.radius, 24), TEAL, 0.05, closed=True)],
        )
        for d in m.detections
    ]


def estimate(m: StateEstimate) -> SceneEntity:
    """The 2-sigma ellipse of the estimated position."""
    cov = np.asarray(m.covariance, dtype=np.float64).reshape(5, 5)  # x, y, theta, v, w
    ring = ellipse_xy(m.x, m.y, cov[:2, :2])
    return entity("estimate", m.stamp, lines=[polyline(ring, ORANGE, 0.06, closed=True)])


def path_in_force(t: float, curve: np.ndarray, control_points: np.ndarray) -> SceneEntity:
    """The path the vehicle follows: its NURBS curve (n, 2) and control polygon (m, 2)."""
    lines = [polyline(curve, GREEN, 0.2), polyline(control_points, PALE_GREEN, 0.04)]
    return entity("path", t, lines=lines)


def replan(t: float, path_id: int, curve: np.ndarray) -> SceneEntity:
    """A path planned before (or the one in force), faint, just under the one in force."""
    return entity(f"replan/{path_id}", t, lines=[polyline(curve, FAINT_GREEN, 0.08, z=-0.01)])
