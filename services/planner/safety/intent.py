"""Other vehicles' intents: where a fleet's vehicles will be, from the paths they broadcast.

Each planner of a fleet publishes the estimate it plans from (planner/pose, while it is alive)
and its newest plan (planner/intent: each new path at once, then again every second, so a lost
one is repaired); a planner that receives both from another vehicle knows that
vehicle's trajectory: along its path from where its estimate puts it, at the speed the
estimate gives, rising to the path's v_ref at that vehicle's speed ramp (controller.speed.
accel_mps2: a vehicle that has just been given a path, at rest at its start, is about to
leave it, not parked there for good: taken as parked, it walled off every goal near its
start), stopping at the path's end (its goal). A vehicle whose newest path is NO_PATH brakes
and holds: it keeps the speed its estimate gives (a stopped vehicle stays put). That is a
moving obstacle with a known trajectory alpha_k(t) for eq. (12)-(13) and for replanning,
better than the constant-acceleration extrapolation of its sonar track, which cannot see a
turn coming. An intent whose estimate is older than `max_age_s` (lost, late, or the vehicle's
planner is dead) is dropped, and the vehicle's track takes over.

Who gives way (planner.deconfliction): "mutual", every vehicle plans around every other's
intent; "priority" (prioritized planning), a vehicle plans around the intents of the vehicles
listed before it in [[vehicles]] and leaves those after it to plan around its own: while
their intents are fresh it ignores their tracks too, so two vehicles never both swerve the
same way at once. A vehicle whose intent goes stale is an obstacle to everyone again, and so
is one parked at the end of its route (its goal): it will not move again, so it can give way
to no one (a vehicle ahead in priority that ignored it would drive through it).
A parked vehicle is where its estimate puts it, at rest, not at its route's last point (a
vehicle that overshot its goal is past it).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import overload

import numpy as np

from common.messages import Message, PathMsg, StateEstimate
from common.world import ObstacleState
from common.world.geometry import Box, FloatArray
from services.planner.geometry.planned_path import curve_of

# samples of a broadcast path: a route polyline fine enough for rho0 at the fleet's sizes
ROUTE_SAMPLES = 400


@dataclass(frozen=True, kw_only=True, slots=True)
class IntentObstacle(ObstacleState):
    """A vehicle following its broadcast route: alpha_k(t) = route(s0 + speed t), clamped at
    the route's end; x, y, vx, vy are its state now (t = 0)."""

    # the route's points, as contiguous x and y (np.interp copies a strided column each call)
    route_x: FloatArray = field(repr=False)  # (m,)
    route_y: FloatArray = field(repr=False)  # (m,)
    s_route: FloatArray = field(repr=False)  # (m,) arc length at each point, from 0
    route_box: Box  # where it can ever be: its centre stays on the route
    s0: float  # arc length now
    speed: float  # m/s along the route now
    cruise: float = 0.0  # m/s it rises to (its path's v_ref) at `ramp`
    ramp: float = 0.0  # m/s^2; 0: the speed holds (a vehicle braking on NO_PATH)

    def centre_at(self, t_s: object, accel_horizon_s: float = np.inf) -> FloatArray:
        """Centre (..., 2) t_s ahead along the route (accel_horizon_s is for extrapolations)."""
        s = self.s0 + self._travel(np.maximum(np.asarray(t_s, dtype=np.float64), 0.0))
        x = np.interp(s, self.s_route, self.route_x)
        y = np.interp(s, self.s_route, self.route_y)
        return np.stack([x, y], axis=-1)

    def advanced(self, dt_s: float) -> IntentObstacle:
        dt = max(dt_s, 0.0)
        return along(self, self.s0 + self._travel(dt), self._speed_after(dt))

    def _rising(self) -> bool:
        return self.ramp > 0.0 and self.speed < self.cruise

    def _speed_after(self, dt_s: float) -> float:
        return min(self.cruise, self.speed + self.ramp * dt_s) if self._rising() else self.speed

    @overload
    def _travel(self, t_s: float) -> float: ...
    @overload
    def _travel(self, t_s: FloatArray) -> FloatArray: ...
    def _travel(self, t_s: float | FloatArray) -> float | FloatArray:
        """Arc length covered in t_s >= 0 (one time, or an array): the speed ramps up to
        cruise, then holds."""
        if not self._rising():
            return self.speed * t_s
        t_up = (self.cruise - self.speed) / self.ramp
        # a plain float for one time: numpy's scalar arithmetic is far slower on one value
        up = min(t_s, t_up) if isinstance(t_s, float) else np.minimum(t_s, t_up)
        return self.speed * up + 0.5 * self.ramp * up * up + self.cruise * (t_s - up)


def along(o: IntentObstacle, s0: float, speed: float | None = None) -> IntentObstacle:
    """The intent with the vehicle at arc length s0 at `speed` (default: its speed now), its
    velocity along the route there (zero once at the route's end)."""
    v = o.speed if speed is None else speed
    end = float(o.s_route[-1])
    s0 = min(max(s0, 0.0), end)
    # the point at s0 and the one 0.5 m ahead (its heading), in one interpolation per axis
    (x, x_ahead), (y, y_ahead) = (
        np.interp((s0, min(s0 + 0.5, end)), o.s_route, axis).tolist()
        for axis in (o.route_x, o.route_y)
    )
    dx, dy = x_ahead - x, y_ahead - y
    n = math.hypot(dx, dy)
    vx, vy = (v * dx / n, v * dy / n) if n > 1e-9 else (0.0, 0.0)
    return replace(o, x=x, y=y, vx=vx, vy=vy, s0=s0, speed=v)


# a broadcast path as a route: polyline x, y; arc length at each point; the points' box
_Route = tuple[FloatArray, FloatArray, FloatArray, Box]


@dataclass
class _Heard:
    state: StateEstimate | None = None
    path: PathMsg | None = None
    route: _Route | None = None
    holding: bool = False  # its newest path is NO_PATH: it brakes, then holds
    # the obstacle at the estimate's stamp, from this state, route and holding (a planner steps
    # several times per pose heard: 10 Hz against 2 Hz); None until asked after a change
    at_stamp: ObstacleState | None = None


class FleetIntents:
    """The newest estimate and path heard from each other vehicle, and their obstacles.

    `vehicles` maps each other vehicle's id to (its obstacle id in sonar tracks, hull radius);
    `gives_way_to` names those whose intents this vehicle plans around (None: all of them);
    `ramps` each one's speed ramp on a path (m/s^2; none: its speed taken as it is);
    `parked_within_m`: a vehicle whose estimate is this near its route's end, or past it,
    is parked there (the goal tolerance); `margin_m`: each hull is planned around this much
    wider (planner.intent_margin_m).
    """

    def __init__(
        self,
        vehicles: Mapping[str, tuple[int, float]],
        max_age_s: float,
        gives_way_to: frozenset[str] | None = None,
        ramps: Mapping[str, float] | None = None,
        parked_within_m: float = 1.0,
        margin_m: float = 0.0,
    ) -> None:
        # another vehicle is only as near its broadcast route as its estimate and its
        # tracking put it, neither of which its intent shows
        self.vehicles = {v: (oid, radius + margin_m) for v, (oid, radius) in vehicles.items()}
        self.max_age_s = max_age_s
        self.parked_within_m = parked_within_m
        self.ramps = dict(ramps or {})
        self.gives_way_to = frozenset(self.vehicles) if gives_way_to is None else gives_way_to
        self._heard = {v: _Heard() for v in self.vehicles}
        # planner steps at which each other vehicle was handled by its fresh intent, or by its
        # sonar track (its intent stale, lost or never heard): what deconfliction rested on
        self.by_intent = dict.fromkeys(self.vehicles, 0)
        self.by_track = dict.fromkeys(self.vehicles, 0)

    def offer(self, vehicle: str, msg: Message) -> bool:
        """Keep `msg` if it is the newest estimate or OK path of another vehicle; False if
        `vehicle` is none of them (the message is someone else's business)."""
        heard = self._heard.get(vehicle)
        if heard is None:
            return False
        if isinstance(msg, StateEstimate):
            if heard.state is None or msg.stamp >= heard.state.stamp:
                heard.state, heard.at_stamp = msg, None
        elif isinstance(msg, PathMsg):
            # the newest only: a path is re-sent (services/mission/fleet.py) with its stamp;
            # after a NO_PATH the last OK path stays its route, but it is braking on it
            if heard.path is None or msg.stamp > heard.path.stamp:
                if msg.status == "OK":
                    heard.path, heard.route, heard.holding = msg, _route_of(msg), False
                else:
                    heard.holding = True
                heard.at_stamp = None
        return True

    def tally(self, t: float) -> None:
        """Count, for this planner step at t, each other vehicle as handled by intent or by
        track."""
        for vid in self.vehicles:
            if self._fresh(vid, t):
                self.by_intent[vid] += 1
            else:
                self.by_track[vid] += 1

    @property
    def counters(self) -> dict[str, int]:
        """The tallies by name: 'intent.<vehicle>', 'track.<vehicle>'."""
        out = {f"intent.{v}": n for v, n in self.by_intent.items()}
        out.update({f"track.{v}": n for v, n in self.by_track.items()})
        return out

    def _fresh(self, vid: str, t: float) -> bool:
        """Whether vehicle vid's intent is usable at t: an estimate at most max_age_s old and a
        route of it."""
        heard = self._heard[vid]
        st = heard.state
        return (
            st is not None
            and heard.route is not None
            and t - st.stamp <= self.max_age_s
            and len(heard.route[0]) >= 2
        )

    def obstacles(self, t: float) -> tuple[tuple[ObstacleState, ...], frozenset[int]]:
        """The intents this vehicle gives way to at time t, and every vehicle parked at its
        route's end, as obstacles at t; and the obstacle ids of every vehicle whose intent is
        fresh (whose sonar tracks they replace: the vehicles it does not give way to plan
        around it)."""
        out: list[ObstacleState] = []
        fresh = set()
        for vid, (oid, radius) in self.vehicles.items():
            if not self._fresh(vid, t):
                continue
            fresh.add(oid)
            heard = self._heard[vid]
            if heard.at_stamp is None:
                heard.at_stamp = self._at_stamp(vid, oid, radius, heard)
            now = heard.at_stamp
            if not isinstance(now, IntentObstacle):
                out.append(now)  # parked at its route's end: an obstacle to everyone
            elif vid in self.gives_way_to:
                st = heard.state
                assert st is not None  # _fresh
                out.append(now.advanced(t - st.stamp))
        return tuple(out), frozenset(fresh)

    def _at_stamp(self, vid: str, oid: int, radius: float, heard: _Heard) -> ObstacleState:
        """Vehicle vid at its estimate's stamp: parked (at or past its route's end), or
        following its route from the route's point nearest the estimate."""
        st, path = heard.state, heard.path
        assert st is not None and heard.route is not None  # _fresh: both are there
        xs, ys, s_route, box = heard.route
        i = int(np.argmin(np.hypot(xs - st.x, ys - st.y)))
        if i == len(xs) - 1 or s_route[-1] - s_route[i] <= self.parked_within_m:
            return _parked(oid, st, radius)
        return IntentObstacle(
            id=oid,
            x=st.x,
            y=st.y,
            vx=0.0,
            vy=0.0,
            ax=0.0,
            ay=0.0,
            radius=radius,
            moving=True,
            route_x=xs,
            route_y=ys,
            s_route=s_route,
            route_box=box,
            s0=float(s_route[i]),
            speed=max(st.v, 0.0),
            cruise=path.v_ref if path is not None else 0.0,
            ramp=0.0 if heard.holding else self.ramps.get(vid, 0.0),
        )


def _parked(oid: int, st: StateEstimate, radius: float) -> ObstacleState:
    """A vehicle at its goal: at rest where its estimate puts it, for good."""
    return ObstacleState(
        id=oid, x=st.x, y=st.y, vx=0.0, vy=0.0, ax=0.0, ay=0.0, radius=radius, moving=True
    )


def _route_of(path: PathMsg) -> _Route:
    """The path's polyline (ROUTE_SAMPLES points, x and y), the arc length at each, its box."""
    curve = curve_of(path)
    u = np.linspace(curve.u_min, curve.u_max, ROUTE_SAMPLES)
    pts = np.asarray(curve.evaluate(u, n_ders=0)[0])
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(pts, axis=0).T))])
    xs, ys = np.ascontiguousarray(pts[:, 0]), np.ascontiguousarray(pts[:, 1])
    return xs, ys, s, Box.of(xs, ys)
