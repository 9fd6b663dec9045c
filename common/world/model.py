"""The world model: obstacles at time t and the safety clearance of eq. (12)."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from common.config.world import WorldConfig
from common.messages import Track
from common.world.geometry import (
    PolygonEdges,
    polygon_centroid,
    polygon_signed_distance,
    vertices_array,
)
from common.world.trajectory import Trajectory, make_trajectory

FloatArray = NDArray[np.float64]
Vec2 = FloatArray | tuple[float, float]  # (2,): x and y components


@dataclass(frozen=True, kw_only=True, slots=True)
class ObstacleState:
    """One obstacle at one time: centre, velocity, acceleration, radius.

    Polygons report their area centroid and circumradius (what a sonar would see); their
    exact geometry is kept inside `World` for the clearance.
    """

    id: int
    x: float
    y: float
    vx: float
    vy: float
    ax: float
    ay: float
    radius: float
    moving: bool

    def centre_at(self, t_s: ArrayLike, accel_horizon_s: float = math.inf) -> FloatArray:
        """Centre (..., 2) predicted t_s ahead, constant acceleration: the one extrapolation.

        alpha_k(t) = p + v t + a t^2 / 2 (eq. (12)), the acceleration held only up to
        `accel_horizon_s`: a tracked acceleration extrapolated for a minute would fling the
        obstacle across the area, so past the horizon it keeps the velocity it has reached.
        """
        if isinstance(t_s, float):  # one time: plain floats, numpy's per-call cost avoided
            return np.array(self._centre(t_s, accel_horizon_s))
        t = np.asarray(t_s, dtype=np.float64)
        ta = np.minimum(t, accel_horizon_s)
        quad = 0.5 * ta * ta + ta * (t - ta)  # integral of min(t, T_a): acceleration term
        x = self.x + self.vx * t + self.ax * quad
        y = self.y + self.vy * t + self.ay * quad
        return np.stack([x, y], axis=-1)

    def _centre(self, t: float, accel_horizon_s: float) -> tuple[float, float]:
        """centre_at at one time, as floats: the same operations in the same order (min
        differs from np.minimum only in the sign of a zero ta, which leaves quad +0.0)."""
        ta = min(t, accel_horizon_s)
        quad = 0.5 * ta * ta + ta * (t - ta)
        return self.x + self.vx * t + self.ax * quad, self.y + self.vy * t + self.ay * quad

    @classmethod
    def of_motion(cls, oid: int, radius: float, pos: Vec2, vel: Vec2, acc: Vec2) -> ObstacleState:
        """The moving obstacle at position `pos` with velocity `vel` and acceleration `acc`."""
        (x, y), (vx, vy), (ax, ay) = (map(float, v) for v in (pos, vel, acc))
        return cls(id=oid, x=x, y=y, vx=vx, vy=vy, ax=ax, ay=ay, radius=radius, moving=True)

    @classmethod
    def of_track(cls, k: Track) -> ObstacleState:
        """The moving obstacle an estimator's track describes (its mean; the covariance is
        not used by eq. (12))."""
        return cls(
            id=k.id, x=k.x, y=k.y, vx=k.vx, vy=k.vy, ax=k.ax, ay=k.ay, radius=k.radius, moving=True
        )

    def advanced(self, dt_s: float) -> ObstacleState:
        """The same obstacle with its state extrapolated dt_s ahead (acceleration held)."""
        x, y = self._centre(dt_s, math.inf)
        return dataclasses.replace(
            self,
            x=float(x),  # (a numpy dt_s makes numpy scalars: the fields stay floats)
            y=float(y),
            vx=self.vx + self.ax * dt_s,
            vy=self.vy + self.ay * dt_s,
        )


@dataclass(frozen=True, kw_only=True, slots=True)
class _Polygon:
    id: int
    vertices: FloatArray
    cx: float
    cy: float
    circumradius: float
    edges: PolygonEdges  # its edges, stacked once for the exact distance


class World:
    """Static circles and polygons plus moving circles following alpha_k(t)."""

    def __init__(self, cfg: WorldConfig) -> None:
        self.cfg = cfg
        self._circle_ids = tuple(c.id for c in cfg.circles)
        self._cxy = np.array([(c.x_m, c.y_m) for c in cfg.circles], dtype=np.float64)
        self._cr = np.array([c.radius_m for c in cfg.circles], dtype=np.float64)
        # (id, x, y, radius) as Python floats, the same values: `nearest` runs at every step of
        # the plant, and arithmetic on numpy scalars costs several times a float's
        self._circles = [
            (cid, float(cx), float(cy), float(cr))
            for cid, (cx, cy), cr in zip(self._circle_ids, self._cxy, self._cr, strict=True)
        ]
        self._polygons: list[_Polygon] = []
        for p in cfg.polygons:
            v = vertices_array(p.vertices_m)
            cx, cy = polygon_centroid(v)
            rc = float(np.max(np.hypot(v[:, 0] - cx, v[:, 1] - cy)))
            self._polygons.append(
                _Polygon(
                    id=p.id, vertices=v, cx=cx, cy=cy, circumradius=rc, edges=PolygonEdges.of([v])
                )
            )
        self._moving: list[tuple[int, float, Trajectory]] = [
            (m.id, m.radius_m, make_trajectory(m)) for m in cfg.moving
        ]
        # the static obstacles' states are the same at every time (and immutable): built once
        self._static: tuple[ObstacleState, ...] = tuple(
            _static(cid, cx, cy, cr) for cid, cx, cy, cr in self._circles
        ) + tuple(_static(p.id, p.cx, p.cy, p.circumradius) for p in self._polygons)
        # obstacles_at's order, static then moving stably sorted by id, as positions in that list
        ids = [o.id for o in self._static] + [m[0] for m in self._moving]
        self._by_id = sorted(range(len(ids)), key=ids.__getitem__)
        self.obstacle_ids: tuple[int, ...] = tuple(ids[i] for i in self._by_id)

    def obstacles_at(self, t: float) -> tuple[ObstacleState, ...]:
        """Every obstacle at time t (s), sorted by id."""
        out = self._static + self.moving_at(t)
        return tuple([out[i] for i in self._by_id])

    def moving_at(self, t: float) -> tuple[ObstacleState, ...]:
        """The moving obstacles at time t (s), in their configured order: obstacles_at's
        moving ones, without building the static ones."""
        t = float(t)  # a numpy time would make every field a numpy scalar
        return tuple([_moving(mid, r, *traj.motion_at(t)) for mid, r, traj in self._moving])

    def clearance(self, x: float, y: float, r_vehicle: float, t: float) -> float:
        """eq. (12): min_k ||x - alpha_k(t)|| - (r + r_k); negative means collision.

        Polygons use the exact signed distance to their boundary minus r. +inf when empty.
        """
        return self.nearest(x, y, r_vehicle, t)[1]

    def nearest(
        self, x: float, y: float, r_vehicle: float, t: float, *, moving: bool = True
    ) -> tuple[int | None, float]:
        """The obstacle that attains eq. (12)'s minimum at (x, y, t), and that clearance.

        (None, +inf) when there is no obstacle; `moving=False` looks at static ones only.
        """
        best, who = math.inf, None
        for cid, cx, cy, cr in self._circles:
            d = math.hypot(x - cx, y - cy) - (r_vehicle + cr)
            if d < best:
                best, who = float(d), cid
        for p in self._polygons:
            # the polygon lies in the disc (centroid, circumradius): if even that disc is no
            # nearer than the best so far, the exact distance cannot change the minimum
            if math.hypot(x - p.cx, y - p.cy) - p.circumradius - r_vehicle >= best:
                continue
            d = float(p.edges.signed_distances(np.array([[x, y]]))[0, 0]) - r_vehicle
            if d < best:
                best, who = d, p.id
        for mid, rk, traj in self._moving if moving else ():
            px, py = traj.position_at(t)
            d = math.hypot(x - px, y - py) - (r_vehicle + rk)
            if d < best:
                best, who = d, mid
        return who, best

    def clearance_many(
        self, xs: ArrayLike, ys: ArrayLike, r_vehicle: ArrayLike, ts: ArrayLike
    ) -> FloatArray:
        """eq. (12) over whole trajectories: xs, ys, r, ts broadcast to one shape."""
        bx, by, br, bt = np.broadcast_arrays(
            *(np.asarray(a, dtype=np.float64) for a in (xs, ys, r_vehicle, ts))
        )
        best = np.full(bx.shape, np.inf)
        if len(self._circle_ids):
            d = np.hypot(bx[..., None] - self._cxy[:, 0], by[..., None] - self._cxy[:, 1])
            best = np.minimum(best, np.min(d - self._cr, axis=-1) - br)
        for p in self._polygons:
            best = np.minimum(best, polygon_signed_distance(p.vertices, bx, by) - br)
        for _, rk, traj in self._moving:
            pos, _, _ = traj.state(bt)
            d = np.hypot(bx - pos[..., 0], by - pos[..., 1]) - (br + rk)
            best = np.minimum(best, d)
        return best


def _static(oid: int, x: float, y: float, r: float) -> ObstacleState:
    return ObstacleState(id=oid, x=x, y=y, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=r, moving=False)


def _moving(
    oid: int, r: float, x: float, y: float, vx: float, vy: float, ax: float, ay: float
) -> ObstacleState:
    """The moving obstacle of radius r (m) with a trajectory's motion at one time."""
    return ObstacleState(id=oid, x=x, y=y, vx=vx, vy=vy, ax=ax, ay=ay, radius=r, moving=True)
