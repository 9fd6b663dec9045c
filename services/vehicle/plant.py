"""The vehicle's plant, chosen by vehicle.model: the unicycle with lags, or Fossen's REMUS 100.

- "unicycle" (dynamics.py): eq. (7) with a speed loop on eq. (14)'s drag and a first-order yaw
  loop, the turn bounded by |w| <= v / R_min. It is the planner's own prediction model
  (services/control/command/response.py), so it tests the loop against itself.
- "fossen3dof" (fossen.py): surge, sway and yaw of the REMUS 100 after Fossen with
  Prestero's coefficients, its propeller and rudder with their limits and the vehicle's own
  speed and yaw-rate autopilots. Nothing bounds its turn but its hydrodynamics and rudder:
  the controllers' R_min is theirs to keep, and the metrics measure whether they did.

Both move relative to the water, carried by the current, and integrate one RK4 step of a
held (v, w) command at a time (the vehicle core splits its grid where the command changes).
"""

from __future__ import annotations

from typing import Protocol

from common.config.vehicle import VehicleConfig
from common.world.current import CurrentFn
from services.vehicle.dynamics import PlantParams, drag_n, make_rk4_step, thrust_n
from services.vehicle.fossen import FossenPlant

PlantState = tuple[float, ...]
# (x, y, theta, v, sway, w): position (m), heading (rad, not wrapped), surge and sway through
# the water (m/s, body frame), yaw rate (rad/s)
Motion = tuple[float, float, float, float, float, float]


class Plant(Protocol):
    """A plant state's start, one RK4 step, and what it shows of its motion."""

    def initial(
        self, x: float, y: float, theta: float, v: float = 0.0, sway: float = 0.0, w: float = 0.0
    ) -> PlantState:
        """A state at (x, y, theta) moving so, its actuators and autopilots at rest on it."""
        ...

    def step(self, s: PlantState, h: float, t0: float, v_cmd: float, w_cmd: float) -> PlantState:
        """One RK4 step of h seconds from time t0 under (v_cmd, w_cmd), in the plant's water."""
        ...

    def motion(self, s: PlantState) -> Motion:
        """(x, y, theta, v, sway, w) of a state."""
        ...

    def thrust_n(self, s: PlantState, v_cmd: float) -> float:
        """The propeller's thrust in state s under a speed command (N)."""
        ...

    def drag_n(self, s: PlantState) -> float:
        """The hull's surge resistance in state s (N)."""
        ...


class UnicyclePlant:
    """dynamics.py behind the Plant protocol: state (x, y, theta, v, w, z), no sway."""

    def __init__(self, cfg: VehicleConfig, current: CurrentFn | None = None) -> None:
        self.p = PlantParams.from_config(cfg)
        self.current = current  # None: still water (rk4_step then makes no call at all)
        self._step = make_rk4_step(self.p)

    def initial(
        self, x: float, y: float, theta: float, v: float = 0.0, sway: float = 0.0, w: float = 0.0
    ) -> PlantState:
        return (x, y, theta, v, w, 0.0)

    def step(self, s: PlantState, h: float, t0: float, v_cmd: float, w_cmd: float) -> PlantState:
        x, y, th, v, w, z = s
        return self._step((x, y, th, v, w, z), h, v_cmd, w_cmd, t0, self.current)

    def motion(self, s: PlantState) -> Motion:
        return s[0], s[1], s[2], s[3], 0.0, s[4]

    def thrust_n(self, s: PlantState, v_cmd: float) -> float:
        return thrust_n(v_cmd, drag_n(v_cmd, self.p), s[3], s[5], self.p)[0]

    def drag_n(self, s: PlantState) -> float:
        return drag_n(s[3], self.p)


def _still(x: float, y: float, t: float) -> tuple[float, float]:
    return 0.0, 0.0


class Fossen3DofPlant:
    """fossen.py behind the Plant protocol: (x, y, psi, u, v, r, thrust, rudder, z_u, z_r)."""

    def __init__(self, cfg: VehicleConfig, current: CurrentFn | None = None) -> None:
        self.fossen = FossenPlant(cfg.fossen, v_max_mps=cfg.v_max_mps)
        self.current = _still if current is None else current  # fossen.py always calls it

    def initial(
        self, x: float, y: float, theta: float, v: float = 0.0, sway: float = 0.0, w: float = 0.0
    ) -> PlantState:
        return self.fossen.initial(x, y, theta, v, sway, w)

    def step(self, s: PlantState, h: float, t0: float, v_cmd: float, w_cmd: float) -> PlantState:
        return self.fossen.step(s, h, t0, v_cmd, w_cmd, self.current)

    def motion(self, s: PlantState) -> Motion:
        return s[0], s[1], s[2], s[3], s[4], s[5]

    def thrust_n(self, s: PlantState, v_cmd: float) -> float:
        return s[6]

    def drag_n(self, s: PlantState) -> float:
        return self.fossen.drag_n(s[3])


def make_plant(cfg: VehicleConfig, current: CurrentFn | None = None) -> Plant:
    """The plant vehicle.model names, moving in the water's velocity `current(x, y, t)` (world
    frame, m/s; None: still water)."""
    if cfg.model == "fossen3dof":
        return Fossen3DofPlant(cfg, current)
    return UnicyclePlant(cfg, current)
