"""Plane geometry as Foxglove scene primitives: stamps, yaw poses, circles, 2-sigma ellipses.

Everything lies in the x-y plane of the frame "world" (the scenario's metres, x east, y north,
z up), so a top-down 3D panel shows the chart as the planner sees it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from foxglove.messages import (
    ArrowPrimitive,
    Color,
    CylinderPrimitive,
    LinePrimitive,
    LinePrimitiveLineType,
    Point3,
    Pose,
    Quaternion,
    TextPrimitive,
    Timestamp,
    Vector3,
)

WORLD = "world"  # the one fixed frame every view message is drawn in
CIRCLE_SEGMENTS = 48  # vertices of a drawn circle or ellipse: smooth at a chart's scale
SIGMAS = 2.0  # uncertainty drawn at 2 sigma (~86 % of a 2-D Gaussian's mass)


def stamp(t_s: float) -> Timestamp:
    """A mission time (s, the runtime clock) as a Foxglove Timestamp (s, ns)."""
    t = max(0.0, t_s)
    sec = math.floor(t)
    nsec = min(999_999_999, round((t - sec) * 1e9))
    return Timestamp(sec, nsec)


def rgba(hex_rgb: str, a: float = 1.0) -> Color:
    """A Color from '#rrggbb' and an alpha in [0, 1]."""
    h = hex_rgb.lstrip("#")
    r, g, b = (int(h[i : i + 2], 16) / 255.0 for i in (0, 2, 4))
    return Color(r=r, g=g, b=b, a=a)


def yaw_quaternion(theta_rad: float) -> Quaternion:
    """A rotation by theta about z (counter-clockwise from x): q = (0, 0, sin, cos)(theta/2)."""
    half = 0.5 * theta_rad
    return Quaternion(x=0.0, y=0.0, z=math.sin(half), w=math.cos(half))


def yaw_pose(x: float, y: float, theta_rad: float = 0.0, z: float = 0.0) -> Pose:
    """A pose at (x, y, z) heading theta."""
    return Pose(position=Vector3(x=x, y=y, z=z), orientation=yaw_quaternion(theta_rad))


def points(xy: Sequence[tuple[float, float]] | np.ndarray, z: float = 0.0) -> list[Point3]:
    """Point3s of (n, 2) plane coordinates."""
    return [Point3(x=float(p[0]), y=float(p[1]), z=z) for p in xy]


def polyline(
    xy: Sequence[tuple[float, float]] | np.ndarray,
    color: Color,
    thickness_m: float,
    *,
    closed: bool = False,
    z: float = 0.0,
) -> LinePrimitive:
    """A line through (n, 2) points, closed into a loop if asked (thickness in metres)."""
    kind = LinePrimitiveLineType.LineLoop if closed else LinePrimitiveLineType.LineStrip
    return LinePrimitive(
        type=kind,
        pose=yaw_pose(0.0, 0.0),
        thickness=thickness_m,
        points=points(xy, z),
        color=color,
    )


def circle_xy(x: float, y: float, r: float, n: int = CIRCLE_SEGMENTS) -> np.ndarray:
    """(n, 2) vertices of the circle of radius r about (x, y)."""
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    return np.column_stack([x + r * np.cos(a), y + r * np.sin(a)])


def ellipse_xy(
    x: float, y: float, cov_xy: np.ndarray, grow_m: float = 0.0, n: int = CIRCLE_SEGMENTS
) -> np.ndarray:
    """(n, 2) vertices of the SIGMAS-sigma ellipse of a 2x2 position covariance about (x, y),
    each semi-axis grown by grow_m (an obstacle's radius: where its hull may be at 2 sigma).

    Semi-axes along the eigenvectors of cov: a_i = SIGMAS sqrt(lambda_i) + grow_m.
    """
    cov = 0.5 * (cov_xy + cov_xy.T)  # symmetric, whatever rounding the wire left
    lam, vec = np.linalg.eigh(cov)
    axes = SIGMAS * np.sqrt(np.clip(lam, 0.0, None)) + grow_m
    a = np.linspace(0.0, 2.0 * math.pi, n, endpoint=False)
    unit = np.column_stack([axes[0] * np.cos(a), axes[1] * np.sin(a)])
    return np.array([x, y]) + unit @ vec.T


def disc(x: float, y: float, r: float, color: Color, height_m: float = 0.4) -> CylinderPrimitive:
    """A flat cylinder of radius r standing on the plane at (x, y)."""
    return CylinderPrimitive(
        pose=yaw_pose(x, y, 0.0, z=0.5 * height_m),
        size=Vector3(x=2.0 * r, y=2.0 * r, z=height_m),
        bottom_scale=1.0,  # both default to 0, which draws nothing
        top_scale=1.0,
        color=color,
    )


def arrow(
    x: float, y: float, vx: float, vy: float, horizon_s: float, color: Color
) -> ArrowPrimitive:
    """An arrow from (x, y) to where velocity (vx, vy) leads in horizon_s seconds."""
    length = math.hypot(vx, vy) * horizon_s
    head = min(0.6, 0.5 * length)
    return ArrowPrimitive(
        pose=yaw_pose(x, y, math.atan2(vy, vx), z=0.05),
        shaft_length=max(0.0, length - head),
        shaft_diameter=0.08,
        head_length=head,
        head_diameter=0.3,
        color=color,
    )


def label(x: float, y: float, text: str, color: Color, size_px: float = 12.0) -> TextPrimitive:
    """A billboard text at (x, y), a constant size on screen."""
    return TextPrimitive(
        pose=yaw_pose(x, y, 0.0, z=0.6),
        billboard=True,
        font_size=size_px,
        scale_invariant=True,
        color=color,
        text=text,
    )
