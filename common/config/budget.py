"""The work budget of a run: its memory and wall time estimated from the scenario, before it runs.

A scenario can ask for work no machine of ours can do: a 10 km x 10 km area or a 1 mm
planner grid allocates terabytes, `run.max_time_s = 1e9` or `vehicle.dt_internal_s = 1e-7`
runs for years. `check_budget` estimates, from the same quantities the code allocates and
loops over, three costs of the AUV mission's run and refuses one over its budget, naming the
key that makes it large, the estimate and the budget:

- the planner's peak memory in one replan: its grid has nx * ny cells (`grid_shape`, the
  shape services/planner/costmap.py allocates) and a replan holds, per cell, the cost map
  and the search graph (one arc per neighbour: 8 or 16);
- the run's record: every message a run publishes is kept in memory until its metrics are
  computed (common/runtime/model/record.py), the services' rates times run.max_time_s;
- the run's wall time: every period of every service, every RK4 step of the vehicle
  (run.max_time_s / vehicle.dt_internal_s) and every prediction sub-step of the estimator
  (at most estimator.max_predict_dt_s long), at their measured costs; a realtime run also
  lasts run.max_time_s / runtime.time_scale.

The unit costs were measured with scripts/bench_budget.py, which also prints each estimate
beside the real allocation or duration. The estimates describe the AUV mission's services
(the scenario sections they read); another mission's own work is its own to bound.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

from common.config.errors import ConfigError
from common.config.planner import grid_shape
from common.config.run import RunConfig
from common.config.sensor import SensorConfig
from common.config.world import AreaConfig

if TYPE_CHECKING:
    from common.config.scenario import Scenario

GIB = 2**30
HOUR_S = 3600.0

# --- budgets: what one run may take on this machine class (2 cores and ~24 GiB shared by
# about six users, i.e. a few GiB each; a sweep runs one run per core at once)
# One replan's peak: 1 GiB keeps the planner process within a user's share with room for
# the rest of the run; it is 4e6 cells with the default search (e.g. 1 km x 1 km at 0.5 m),
# whose Dijkstra takes ~5 s a replan here, already far beyond a replan of the paper's field.
PLANNER_BYTES_BUDGET = 1 * GIB
# The record of a run: 1 GiB is ~1e6 messages, over 3 hours of mission at the default rates.
RECORD_BYTES_BUDGET = 1 * GIB
# A run stays under an hour: a sweep runs dozens of them and a typo must not hold the
# machine for days (the default mission takes ~7 s in lockstep).
WALL_BUDGET_S = 1 * HOUR_S

# --- unit costs, measured by scripts/bench_budget.py on this machine (2 cores, 2026-11)
# Bytes a grid cell costs at a replan's peak: a fixed part and a part per arc (per
# neighbour: connectivity 8 or 16). Dijkstra: per arc the CSR column index (intp, kept
# between replans), its weight (float64) and the contiguous copy edge_weights returns, 24 B;
# per cell the cost map (clearance, static clearance, cost: float64; blocked: bool; 25 B),
# the row pointers and the scratch of the map and of scipy's Dijkstra (distances,
# predecessors), 72 B in all. A* adds Python lists of every arc's weight and column (an
# object and a pointer each) and per-cell lists of g, h and parents.
GRID_BYTES_FIXED = {"dijkstra": 72, "astar": 260}
GRID_BYTES_PER_ARC = {"dijkstra": 24, "astar": 99}
# A message kept in the record (its decoded struct, arrays and the record's dict slot).
RECORD_BYTES_PER_MESSAGE = 1040
# Wall seconds of one service period (its core's step, encoding, routing, recording),
# averaged over the AUV mission's services: one process (inproc), or one process per
# service ticked over Zenoh (lockstep; realtime runs the same processes).
SERVICE_STEP_S = {"inproc": 0.37e-3, "lockstep": 1.3e-3, "realtime": 1.3e-3}
# One RK4 step of the vehicle plant (services/vehicle/core.py).
RK4_STEP_S = 13e-6
# One prediction sub-step of the estimator's vehicle filter.
PREDICT_STEP_S = {"ekf": 18e-6, "ukf": 210e-6}
# Mission seconds the estimator predicts over per mission second: each fix, each
# publication and the re-fusion of out-of-sequence fixes predict again (measured 2.5).
PREDICT_PASSES = 2.5
# The AUV mission's services (sensor, estimator, planner, vehicle) each publish stats.
N_SERVICES = 4


@dataclass(frozen=True, kw_only=True)
class Budget:
    """The limits a run is checked against (`tidelink ... --budget FACTOR` scales them)."""

    planner_bytes: float = PLANNER_BYTES_BUDGET
    record_bytes: float = RECORD_BYTES_BUDGET
    wall_s: float = WALL_BUDGET_S

    def scaled(self, factor: float) -> Budget:
        return Budget(
            planner_bytes=self.planner_bytes * factor,
            record_bytes=self.record_bytes * factor,
            wall_s=self.wall_s * factor,
        )


DEFAULT_BUDGET = Budget()


@dataclass(frozen=True, kw_only=True)
class Estimate:
    """What a run of the scenario will take: memory (bytes), work counts and wall time (s)."""

    grid_cells: float  # the planner's cost map, nx * ny (inf past float range)
    grid_bytes_per_cell: int  # at a replan's peak, for the configured search
    messages: float  # published over the run, all kept in the record
    service_steps: float  # periods of every service, stats included
    rk4_steps: float  # the vehicle plant's integration steps
    predict_steps: float  # the estimator's prediction sub-steps
    wall_terms_s: dict[str, float]  # wall time by cause: steps, rk4, predict, realtime

    @property
    def planner_bytes(self) -> float:
        return self.grid_cells * self.grid_bytes_per_cell

    @property
    def record_bytes(self) -> float:
        return self.messages * RECORD_BYTES_PER_MESSAGE

    @property
    def wall_s(self) -> float:
        """Compute adds up; a realtime run lasts at least its mission time over the scale."""
        compute = sum(v for k, v in self.wall_terms_s.items() if k != "realtime")
        return max(compute, self.wall_terms_s.get("realtime", 0.0))

    def summary(self) -> str:
        """One line for `tidelink check`."""
        return (
            f"planner grid {self.grid_cells:.3g} cells (~{_bytes(self.planner_bytes)} a "
            f"replan), record ~{self.messages:.3g} messages (~{_bytes(self.record_bytes)}), "
            f"wall time ~{_duration(self.wall_s)}"
        )


def estimate(s: Scenario) -> Estimate:
    """The scenario's run, estimated from the quantities its services allocate and loop over."""
    p, t = s.planner, s.run.max_time_s
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
        terms["realtime"] = t / s.runtime.time_scale
    return Estimate(
        grid_cells=cells,
        grid_bytes_per_cell=per_cell,
        messages=t * message_rate_hz(s),
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


def check_budget(s: Scenario, file: str = "", budget: Budget = DEFAULT_BUDGET) -> None:
    """Raise ConfigError naming the key that makes the run exceed a budget, the estimate and
    the budget; nothing is allocated."""
    est = estimate(s)
    more = "; --budget FACTOR allows FACTOR times every budget"
    if est.planner_bytes > budget.planner_bytes:
        finer = _ratio_below(s.planner, "resolution_m")
        key = _blame(
            ("planner.resolution_m", finer * finer),  # (a product: ** raises on overflow)
            ("world.area", _area_m2(s.world.area) / _area_m2(AreaConfig())),
        )
        a, p = s.world.area, s.planner
        size = f"{a.x_max_m - a.x_min_m:g} m × {a.y_max_m - a.y_min_m:g} m"
        grid = (
            f"planner.resolution_m={p.resolution_m:g} over a {size} area"
            if key == "planner.resolution_m"
            else f"world.area of {size} at planner.resolution_m={p.resolution_m:g}"
        )
        raise ConfigError(
            file,
            _path(key),
            f"{grid} is a {est.grid_cells:.3g}-cell cost map (~{_bytes(est.planner_bytes)} at "
            f"a replan's peak, {est.grid_bytes_per_cell} B a cell with {p.search} and "
            f"{p.connectivity} neighbours); the budget is "
            f"{budget.planner_bytes / est.grid_bytes_per_cell:.3g} cells "
            f"(~{_bytes(budget.planner_bytes)}): coarsen the resolution or shrink world.area"
            + more,
        )
    if est.record_bytes > budget.record_bytes:
        key = _blame(_longer(s), *_rates(s))
        raise ConfigError(
            file,
            _path(key),
            f"{_cause(s, key, message_rate_hz(s), 'messages', est.messages)}, all kept in the "
            f"run's record (~{_bytes(est.record_bytes)} at ~{RECORD_BYTES_PER_MESSAGE} B each); "
            f"the budget is {_bytes(budget.record_bytes)} "
            f"({budget.record_bytes / RECORD_BYTES_PER_MESSAGE:.3g} messages): shorten "
            "run.max_time_s or publish less often" + more,
        )
    if est.wall_s > budget.wall_s:
        key, what, fix = _wall_cause(s, est)
        parts = ", ".join(f"{_TERM_NAMES[k]} ~{_duration(v)}" for k, v in est.wall_terms_s.items())
        raise ConfigError(
            file,
            _path(key),
            f"{what}: the run would take ~{_duration(est.wall_s)} of wall time "
            f"({s.runtime.kind}: {parts}); the budget is {_duration(budget.wall_s)}: {fix}" + more,
        )


_TERM_NAMES = {
    "steps": "service periods",
    "rk4": "vehicle RK4 steps",
    "predict": "estimator predictions",
    "realtime": "mission time / time_scale",
}


def _wall_cause(s: Scenario, est: Estimate) -> tuple[str, str, str]:
    """(key, what it makes, the remedy) of the largest part of the wall-time estimate."""
    t = s.run.max_time_s
    term = max(est.wall_terms_s, key=lambda k: est.wall_terms_s[k])
    if term == "rk4":
        key = _blame(
            _longer(s), ("vehicle.dt_internal_s", _ratio_below(s.vehicle, "dt_internal_s"))
        )
        per_period = s.vehicle.period_s / s.vehicle.dt_internal_s
        what = (
            f"vehicle.dt_internal_s={s.vehicle.dt_internal_s:g} over run.max_time_s={t:g} is "
            f"{est.rk4_steps:.3g} RK4 steps ({per_period:.3g} a vehicle period, "
            f"~{RK4_STEP_S * 1e6:g} µs each)"
        )
        return key, what, "raise vehicle.dt_internal_s or shorten run.max_time_s"
    if term == "predict":
        ratio = _ratio_below(s.estimator, "max_predict_dt_s")
        key = _blame(_longer(s), ("estimator.max_predict_dt_s", ratio))
        what = (
            f"estimator.max_predict_dt_s={s.estimator.max_predict_dt_s:g} over "
            f"run.max_time_s={t:g} is {est.predict_steps:.3g} prediction sub-steps"
        )
        return key, what, "raise estimator.max_predict_dt_s or shorten run.max_time_s"
    if term == "realtime":
        ratio = _ratio_below(s.runtime, "time_scale")
        key = _blame(_longer(s), ("runtime.time_scale", ratio))
        what = (
            f"a realtime run of run.max_time_s={t:g} at runtime.time_scale={s.runtime.time_scale:g}"
        )
        return key, what, "shorten run.max_time_s or raise runtime.time_scale"
    key = _blame(_longer(s), *_rates(s))
    rate = est.service_steps / t
    what = (
        f"{_cause(s, key, rate, 'service periods', est.service_steps)} "
        f"(~{SERVICE_STEP_S[s.runtime.kind] * 1e3:g} ms each)"
    )
    return key, what, "shorten run.max_time_s or lengthen the services' periods"


def _cause(s: Scenario, key: str, rate: float, unit: str, count: float) -> str:
    """How `key` makes `count` of `unit` at `rate` a mission second, said from its side."""
    t = s.run.max_time_s
    if key == "run.max_time_s":
        return f"run.max_time_s={t:g} at {rate:.3g} {unit} a mission second is {count:.3g} {unit}"
    return (
        f"{key}={_value(s, key):g} makes {rate:.3g} {unit} a mission second, {count:.3g} over "
        f"run.max_time_s={t:g}"
    )


def _longer(s: Scenario) -> tuple[str, float]:
    """run.max_time_s with how many times its default it is (listed first: it wins ties)."""
    return "run.max_time_s", s.run.max_time_s / RunConfig().max_time_s


def _rates(s: Scenario) -> list[tuple[str, float]]:
    """Each rate key with how many times its default rate it runs (a period: the inverse)."""
    sensor = SensorConfig()
    return [
        ("vehicle.period_s", _ratio_below(s.vehicle, "period_s")),
        ("sensor.nav_rate_hz", s.sensor.nav_rate_hz / sensor.nav_rate_hz),
        ("sensor.obstacle_rate_hz", s.sensor.obstacle_rate_hz / sensor.obstacle_rate_hz),
        ("estimator.period_s", _ratio_below(s.estimator, "period_s")),
        ("planner.period_s", _ratio_below(s.planner, "period_s")),
        ("runtime.stats_period_s", _ratio_below(s.runtime, "stats_period_s")),
    ]


def _ratio_below(cfg: object, name: str) -> float:
    """How many times smaller than its default a step, period or scale is (the work it
    multiplies); the default is the config dataclass's own."""
    default = getattr(type(cfg)(), name)
    return float(default / getattr(cfg, name))


def _blame(*factors: tuple[str, float]) -> str:
    """The key whose value multiplies the work the most against its default: the one an
    error names (the first on a tie)."""
    return max(factors, key=lambda f: f[1])[0]


def _value(s: Scenario, key: str) -> float:
    section, name = key.split(".")
    return float(getattr(getattr(s, section), name))


def _path(key: str) -> tuple[str, ...]:
    return tuple(key.split("."))


def _area_m2(a: AreaConfig) -> float:
    return (a.x_max_m - a.x_min_m) * (a.y_max_m - a.y_min_m)


def _bytes(n: float) -> str:
    for unit, size in (("TiB", 2**40), ("GiB", 2**30), ("MiB", 2**20), ("KiB", 2**10)):
        if n >= size:
            return f"{n / size:.3g} {unit}"
    return f"{n:.0f} B"


def _duration(s: float) -> str:
    for unit, size in (("years", 365.25 * 86400), ("days", 86400), ("h", 3600), ("min", 60)):
        if s >= size:
            return f"{s / size:.3g} {unit}"
    return f"{s:.3g} s"
