"""What one run of a scenario will take: memory and wall time, estimated before it runs.

Estimated from the same quantities the code allocates and loops over, at unit costs
measured by scripts/bench_budget.py (which prints each estimate beside the real allocation
or duration):

- the planner's peak memory in one replan: its grid has nx * ny cells (`grid_shape`, the
  shape services/planner/search/costmap.py allocates) and a replan holds, per cell, the cost map
  and the search graph (one arc per neighbour: 8 or 16);
- the run's record: every message a run publishes is kept in memory until its metrics are
  computed (common/runtime/model/record.py), the services' rates times run.max_time_s;
- the run's wall time: every period of every service, every RK4 step of the vehicle
  (run.max_time_s / vehicle.dt_internal_s) and every prediction sub-step of the estimator
  (at most estimator.max_predict_dt_s long), at their measured costs; a realtime run also
  lasts run.max_time_s / runtime.time_scale.

The estimates describe the AUV mission's services (the scenario sections they read);
another mission's own work is its own to bound. common/config/budget.py checks them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from common.config.planner import grid_shape

if TYPE_CHECKING:
    from common.config.scenario import Scenario

# --- unit costs, from scripts/bench_budget.py on the project's 2-core machine
# Bytes a grid cell costs at a replan's peak: a fixed part and a part per arc (per
# neighbour: connectivity 8 or 16). Dijkstra: per arc the CSR column index (intp, kept
# between replans) and its weight (float64, written in the CSR layout at once), 16 B, and
# the scratch of summing it, ~19 B in all; per cell the cost map (clearance, static
# clearance, cost: float64; blocked: bool; 25 B), the row pointers and the scratch of the
# map and of scipy's Dijkstra (distances, predecessors), 88 B in all (fitted to the resident
# growth at K = 8 and 16). A* adds Python lists of every arc's weight and column (an object
# and a pointer each) and per-cell lists of g, h and parents.
GRID_BYTES_FIXED = {"dijkstra": 88, "astar": 260}
GRID_BYTES_PER_ARC = {"dijkstra": 19, "astar": 99}
# A message kept in the record (its decoded struct, arrays and the record's dict slot).
RECORD_BYTES_PER_MESSAGE = 1040
# Each future entry of a command's sequence kept in the record (two ints and their slots).
RECORD_BYTES_PER_SEQUENCE_ENTRY = 60
# Wall seconds of one service period (its core's step, encoding, routing, recording),
# averaged over the AUV mission's services: one process (inproc), or one process per
# service ticked over Zenoh (lockstep; realtime runs the same processes).
SERVICE_STEP_S = {"inproc": 0.37e-3, "lockstep": 1.3e-3, "realtime": 1.3e-3}
# One RK4 step of the vehicle plant (services/vehicle/core.py).
RK4_STEP_S = 13e-6
# One prediction sub-step of the estimator's vehicle filter.
PREDICT_STEP_S = {"ekf": 18e-6, "ukf": 210e-6}
# Mission seconds the estimator predicts over per mission second: each fix, each
# publication and the re-fusion of out-of-sequence fixes predict again.
PREDICT_PASSES = 2.5
# The AUV mission's services (sensor, estimator, planner, vehicle) each publish stats.
N_SERVICES = 4


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """What a run of the scenario will take: memory (bytes), work counts and wall time (s)."""

    grid_cells: float  # the planner's cost map, nx * ny (inf past float range)
    grid_bytes_per_cell: int  # at a replan's peak, for the configured search
    messages: float  # published over the run, all kept in the record
    sequence_entries: float  # future entries of every command sent (controller.sequence)
    service_steps: float  # periods of every service, stats included
    rk4_steps: float  # the vehicle plant's integration steps
    predict_steps: float  # the estimator's prediction sub-steps
    wall_terms_s: dict[str, float]  # wall time by cause: steps, rk4, predict, realtime

    @property
    def planner_bytes(self) -> float:
        return self.grid_cells * self.grid_bytes_per_cell

    @property
    def record_bytes(self) -> float:
        return (
            self.messages * RECORD_BYTES_PER_MESSAGE
            + self.sequence_entries * RECORD_BYTES_PER_SEQUENCE_ENTRY
        )

    @property
    def wall_s(self) -> float:
        """Compute adds up; a realtime run lasts at least its mission time over the scale."""
        compute = sum(v for k, v in self.wall_terms_s.items() if k != "realtime")
        return max(compute, self.wall_terms_s.get("realtime", 0.0))

    def summary(self) -> str:
        """One line for `tidelink check`."""
        return (
            f"planner grid {self.grid_cells:.3g} cells (~{format_bytes(self.planner_bytes)} a "
            f"replan), record ~{self.messages:.3g} messages (~{format_bytes(self.record_bytes)}), "
            f"wall time ~{format_duration(self.wall_s)}"
        )


def estimate(s: Scenario) -> Estimate:
    """The scenario's run, estimated from the quantities its services allocate and loop over
    (a fleet's vehicles each run the services: its work in time is theirs times their number;
    its planners replan one at a time, so the grid's peak is one planner's)."""
    p = s.planner
    t = s.run.max_time_s * max(1, len(s.vehicles))  # vehicle-seconds
    try:
        nx, ny = grid_shape(s.world.area, p.resolution_m)
        cells = float(nx * ny)
    except OverflowError:  # area / resolution beyond float range: no grid at all
        cells = math.inf
    per_cell = GRID_BYTES_FIXED[p.search] + GRID_BYTES_PER_ARC[p.search] * p.connectivity
    step_rate = (
        1.0 / s.sensor.period_s
        + 1.0 / s.estimator.period_s
        + 1.0 / p.period_s
        + 1.0 / s.vehicle.period_s
        + N_SERVICES / s.runtime.stats_period_s
    )
    service_steps = t * step_rate
    rk4_steps = t / s.vehicle.dt_internal_s
    # each call predicts at least one sub-step: a fix, a publication
    predict_calls = t * (s.sensor.nav_rate_hz + 1.0 / s.estimator.period_s)
    predict_steps = PREDICT_PASSES * t / s.estimator.max_predict_dt_s + predict_calls
    kind = s.runtime.kind
    terms = {
        "steps": service_steps * SERVICE_STEP_S[kind],
        "rk4": rk4_steps * RK4_STEP_S,
        "predict": predict_steps * PREDICT_STEP_S[s.estimator.vehicle_filter],
    }
    if kind == "realtime":
        terms["realtime"] = s.run.max_time_s / s.runtime.time_scale  # the fleet's in parallel
    return Estimate(
        grid_cells=cells,
        grid_bytes_per_cell=per_cell,
        messages=t * message_rate_hz(s),
        sequence_entries=t / p.period_s * s.controller.sequence.entries(p.period_s),
        service_steps=service_steps,
        rk4_steps=rk4_steps,
        predict_steps=predict_steps,
        wall_terms_s=terms,
    )


def message_rate_hz(s: Scenario) -> float:
    """Messages the AUV mission publishes per mission second (services/mission/dataflow.py):
    vehicle truth + status, sensor nav and obstacles, estimator state + tracks, planner cmd
    (its rare paths aside), and every service's stats."""
    return (
        2.0 / s.vehicle.period_s
        + s.sensor.nav_rate_hz
        + s.sensor.obstacle_rate_hz
        + 2.0 / s.estimator.period_s
        + 1.0 / s.planner.period_s
        + N_SERVICES / s.runtime.stats_period_s
    )


def format_bytes(n: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def format_duration(s: float) -> str:
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.3g} s"
