"""Planner configuration: cost grid, graph search, NURBS fit/refinement and replan events.

Vehicle radius, minimum turning radius R_min, cruise speed v_ref and the area are not here:
they live in the vehicle / world sections and are handed to the planner as arguments.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Literal

from common.config.checks import int_range, nonneg, positive
from common.config.errors import ConfigValueError
from common.config.planner_tuning import PlannerTuning
from common.config.world import AreaConfig

SearchKind = Literal["dijkstra", "astar"]
RefineMethod = Literal["levenberg_marquardt", "lbfgsb"]


@dataclass(frozen=True, kw_only=True)
class PlannerConfig:
    """Tunables of the replan pipeline (cost map -> graph search -> NURBS fit -> refinement)."""

    period_s: float = 0.1  # check for replans and send a command every period
    # --- cost grid, eq. (5)-(6) and (17)
    resolution_m: float = 0.5  # grid cell size; 100 m x 40 m -> 200 x 80 cells
    rho0_m: float = 1.0  # eq. (6) minimum safe distance (vehicle surface to obstacle surface)
    rho_m: float = 4.0  # eq. (5)-(6) range of the repulsive potential (surface to surface)
    k_r: float = 0.05  # eq. (5)-(6) repulsive constant K_r (m^2; the cost is dimensionless)
    cost_cap: float = 10.0  # cap on the per-cell repulsive cost (eq. (6) diverges at rho0)
    smoothing_len: int = 2  # eq. (17) filter length l in cells (kernel of 2l+1 taps); 0 = off
    # --- graph search, eq. (15)-(16), (18)
    search: SearchKind = "dijkstra"  # dijkstra: scipy csgraph (C); astar: heapq (pure Python)
    connectivity: int = 8  # 8 or 16 neighbours per grid node (16: ~2x search time)
    moving_window_s: float = 3.0  # a moving obstacle blocks its predicted disc over +- this
    accel_horizon_s: float = 5.0  # beyond this, predictions drop the (tracked) acceleration
    escape_len_m: float = 3.0  # a start inside the safety margin may leave it within this
    # --- NURBS fit and refinement, eq. (8)-(13), (19)-(20)
    nurbs_degree: int = 3
    ctrl_spacing_m: float = 6.0  # max spacing of initial control points along the grid path
    samples_per_span: int = 6  # refinement samples per knot span (Gauss-Legendre nodes)
    # levenberg_marquardt: damped Gauss-Newton (numpy); lbfgsb: scipy L-BFGS-B, which needs
    # OPENBLAS_NUM_THREADS=1 in the process environment to be fast on a small shared machine
    refine_method: RefineMethod = "levenberg_marquardt"
    refine_max_iter: int = 12  # solver iterations per refinement round
    refine_rounds: int = 3  # rounds (tighter penalties, more control points) before NO_PATH
    penalty_clearance: float = 1.0e3  # eq. (9) c_n for obstacle constraints (12)-(13)
    penalty_curvature: float = 3.0e2  # eq. (9) c_n for the turning constraint (11)/(20)
    # eq. (19) f_R in the refinement objective, as F_R = int ds / (r - R_min) over arc length
    # (sample-count independent; ~ the total turning in rad on gentle bends): its weight in
    # metres of path length per unit of F_R; 0 leaves f_R out
    penalty_turn: float = 1.0
    # refinement aims this far beyond the required clearance, and keeps the hull this far
    # inside the area's edge
    clearance_margin_m: float = 0.15
    # ... and this much further per second of the loop's measured delay (the estimate's age as
    # it arrives plus the downlink delay the commands are compensated for): the vehicle follows
    # the path on a state predicted that far ahead, and the prediction's error grows with it
    # (at 1 s one-way on every link the loop is ~3.4 s: 0.15 + 0.34 m); 0: a fixed margin
    clearance_margin_per_delay_s: float = 0.1
    # ... and this much further per m/s of the estimated current (s): a current pushes the
    # vehicle off its path in every bend and while it gathers speed, more the stronger it is
    # (0.3 m/s: 0.3 m more); 0: no widening
    clearance_margin_per_current_s: float = 1.0
    curvature_margin: float = 0.85  # refinement aims at k <= curvature_margin / R_min
    n_samples_check: int = 2000  # dense samples of the final checks, eq. (12)-(13), (20)
    # --- replan events
    corridor_halfwidth_m: float = 3.0  # new track predicted this close (hull gap) to the path
    deviation_threshold_m: float = 2.0  # vehicle this far from its path: replan
    min_replan_interval_s: float = 1.0  # no two replans closer than this (no chattering)
    # the estimated current changed by more than this (m/s) since the path in force was
    # flown (rollout.py) before it was adopted: replan, flown in the current as it is now
    current_change_mps: float = 0.1
    # the first plan waits (holding the vehicle still) until the estimator's tracks hold a
    # track, i.e. reflect at least one sonar scan, so eq. (12)-(13) see the moving obstacles
    # in view; from this mission time on it plans with what it has
    first_plan_wait_s: float = 2.0
    # --- networked loop
    # an estimate older than this (uplink outage) makes the planner stop commanding, so the
    # vehicle's watchdog holds it (after its buffer of commands) instead of it steering on a
    # pose extrapolated too far; older *beyond* the delay measured on the estimate input (the
    # median age of the last delay_window estimates as they arrived): a known delay is no outage
    max_estimate_age_s: float = 1.0
    delay_window: int = 31
    # with the controller onboard (services/tracker) the path in force is sent again this often
    # (s): one lost path message left the tracker on an older path, or none, for good; 0: never
    path_repeat_s: float = 2.0
    # fleets: another vehicle's intent (its broadcast path, placed by its estimate) is used
    # while that estimate is at most this old; then its sonar track takes over
    intent_max_age_s: float = 2.0
    # ... and its hull planned around this much wider: it flies its route only as closely as
    # it tracks it, and is placed on it by its estimate. Off by default: a wider intent
    # made fleet4 touch an obstacle in realtime (docs/notes/0023-intent-margin-off.md)
    intent_margin_m: float = 0.0
    # who plans around whose intent (services/planner/safety/intent.py): "priority", a vehicle gives
    # way to those listed before it in [[vehicles]]; "mutual", to every other vehicle
    deconfliction: Literal["priority", "mutual"] = "priority"
    # plan-and-verify and stepping aside (common/config/planner_tuning.py)
    tuning: PlannerTuning = field(default_factory=PlannerTuning)

    def __post_init__(self) -> None:
        for name in ("resolution_m", "k_r", "cost_cap", "ctrl_spacing_m"):
            positive(name, getattr(self, name))
        for name in ("rho0_m", "moving_window_s", "accel_horizon_s", "escape_len_m"):
            nonneg(name, getattr(self, name))
        for name in (
            "penalty_clearance",
            "penalty_curvature",
            "penalty_turn",
            "clearance_margin_m",
            "clearance_margin_per_delay_s",
            "clearance_margin_per_current_s",
        ):
            nonneg(name, getattr(self, name))
        for name in (
            "corridor_halfwidth_m",
            "deviation_threshold_m",
            "intent_margin_m",
            "min_replan_interval_s",
            "first_plan_wait_s",
            "path_repeat_s",
        ):
            nonneg(name, getattr(self, name))
        positive("period_s", self.period_s)
        positive("current_change_mps", self.current_change_mps)
        positive("max_estimate_age_s", self.max_estimate_age_s)
        positive("intent_max_age_s", self.intent_max_age_s)
        if not (math.isfinite(self.rho_m) and self.rho_m > self.rho0_m):
            raise ConfigValueError(
                "rho_m",
                f"{self.rho_m!r} is invalid, expected a finite value > rho0_m "
                f"({self.rho0_m!r}): the potential range must exceed the safe distance",
            )
        if self.resolution_m > 5.0:
            raise ConfigValueError(
                "resolution_m", f"{self.resolution_m!r} is too coarse, expected <= 5"
            )
        int_range("smoothing_len", self.smoothing_len, 0, 20)
        int_range("delay_window", self.delay_window, 1, 10_000)
        if self.search not in ("dijkstra", "astar"):
            raise ConfigValueError(
                "search", f"{self.search!r} is unknown, expected 'dijkstra' or 'astar'"
            )
        if self.refine_method not in ("levenberg_marquardt", "lbfgsb"):
            raise ConfigValueError(
                "refine_method",
                f"{self.refine_method!r} is unknown, expected 'levenberg_marquardt' or 'lbfgsb'",
            )
        if self.connectivity not in (8, 16):
            raise ConfigValueError(
                "connectivity", f"{self.connectivity!r} is invalid, expected 8 or 16"
            )
        int_range("nurbs_degree", self.nurbs_degree, 2, 5)
        int_range("samples_per_span", self.samples_per_span, 2, 20)
        int_range("refine_max_iter", self.refine_max_iter, 0, 10_000)
        int_range("refine_rounds", self.refine_rounds, 1, 10)
        int_range("n_samples_check", self.n_samples_check, 100, 1_000_000)
        if not (0.0 < self.curvature_margin <= 1.0):
            raise ConfigValueError(
                "curvature_margin", f"{self.curvature_margin!r} is invalid, expected in (0, 1]"
            )


def grid_shape(area: AreaConfig, resolution_m: float) -> tuple[int, int]:
    """(nx, ny) cells covering the area at the given resolution (the planner's cost map; the
    work budget sizes it from here before any planner runs)."""
    nx = max(1, math.ceil((area.x_max_m - area.x_min_m) / resolution_m - 1e-9))
    ny = max(1, math.ceil((area.y_max_m - area.y_min_m) / resolution_m - 1e-9))
    return nx, ny
