"""The work budget of a run: its estimated memory and wall time checked against stated limits.

A scenario can ask for work no machine of ours can do: a 10 km x 10 km area or a 1 mm
planner grid allocates terabytes, `run.max_time_s = 1e9` or `vehicle.dt_internal_s = 1e-7`
runs for years. `check_budget` takes the estimate of common/config/work.py and refuses a
run over a budget before anything is allocated, naming the key that makes the work large
(the one furthest from its default), the estimate and the budget.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from common.config.errors import ConfigError
from common.config.run import RunConfig
from common.config.sensor import SensorConfig
from common.config.work import (
    RECORD_BYTES_PER_MESSAGE,
    RECORD_BYTES_PER_SEQUENCE_ENTRY,
    RK4_STEP_S,
    SERVICE_STEP_S,
    Estimate,
    estimate,
    format_bytes,
    format_duration,
    message_rate_hz,
)
from common.config.world import AreaConfig

if TYPE_CHECKING:
    from common.config.scenario import Scenario

GIB = 2**30
HOUR_S = 3600.0

# --- budgets: what one run may take on this machine class (2 cores and ~24 GiB shared by
# about six users, i.e. a few GiB each; a sweep runs one run per core at once)
# One replan's peak: 1 GiB keeps the planner process within a user's share with room for
# the rest of the run; it is 4e6 cells with the default search (e.g. 1 km x 1 km at 0.5 m),
# whose Dijkstra takes seconds a replan, already far beyond a replan of the paper's field.
PLANNER_BYTES_BUDGET = 1 * GIB
# The record of a run: 1 GiB is ~1e6 messages, over 3 hours of mission at the default rates.
RECORD_BYTES_BUDGET = 1 * GIB
# A run stays under an hour: a sweep runs dozens of them and a typo must not hold the
# machine for days (the default mission takes seconds in lockstep).
WALL_BUDGET_S = 1 * HOUR_S


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
            f"{grid} is a {est.grid_cells:.3g}-cell cost map "
            f"(~{format_bytes(est.planner_bytes)} at a replan's peak, "
            f"{est.grid_bytes_per_cell} B a cell with {p.search} and "
            f"{p.connectivity} neighbours); the budget is "
            f"{budget.planner_bytes / est.grid_bytes_per_cell:.3g} cells "
            f"(~{format_bytes(budget.planner_bytes)}): coarsen the resolution or shrink world.area"
            + more,
        )
    if est.record_bytes > budget.record_bytes:
        key = _blame(_longer(s), *_rates(s))
        raise ConfigError(
            file,
            _path(key),
            f"{_cause(s, key, message_rate_hz(s), 'messages', est.messages)}, all kept in the "
            f"run's record (~{format_bytes(est.record_bytes)} at ~{RECORD_BYTES_PER_MESSAGE} B "
            f"each{_sequence_share(est)}); "
            f"the budget is {format_bytes(budget.record_bytes)}: shorten "
            "run.max_time_s or publish less often" + more,
        )
    if est.wall_s > budget.wall_s:
        key, what, fix = _wall_cause(s, est)
        parts = ", ".join(
            f"{_TERM_NAMES[k]} ~{format_duration(v)}" for k, v in est.wall_terms_s.items()
        )
        raise ConfigError(
            file,
            _path(key),
            f"{what}: the run would take ~{format_duration(est.wall_s)} of wall time "
            f"({s.runtime.kind}: {parts}); the budget is {format_duration(budget.wall_s)}: {fix}"
            + more,
        )


def _sequence_share(est: Estimate) -> str:
    """What the commands' sequences add to the record, if anything."""
    if not est.sequence_entries:
        return ""
    extra = est.sequence_entries * RECORD_BYTES_PER_SEQUENCE_ENTRY
    return (
        f", ~{format_bytes(extra)} of it the {est.sequence_entries:.3g} entries of the commands' "
        "sequences: controller.sequence.horizon_s"
    )


_TERM_NAMES = {
    "steps": "service periods",
    "rk4": "vehicle RK4 steps",
    "predict": "estimator predictions",
    "realtime": "mission time / time_scale",
}


# the wall-time terms one key drives: that key, and the remedy an error gives
_ONE_KEY_TERMS = {
    "rk4": ("vehicle.dt_internal_s", "raise vehicle.dt_internal_s or shorten run.max_time_s"),
    "predict": (
        "estimator.max_predict_dt_s",
        "raise estimator.max_predict_dt_s or shorten run.max_time_s",
    ),
    "realtime": ("runtime.time_scale", "shorten run.max_time_s or raise runtime.time_scale"),
}


def _wall_cause(s: Scenario, est: Estimate) -> tuple[str, str, str]:
    """(key, what it makes, the remedy) of the largest part of the wall-time estimate: its
    one key, or run.max_time_s if the run is longer against its default than the key is
    finer; for the service periods, the rate key that runs fastest against its default."""
    t = s.run.max_time_s
    term = max(est.wall_terms_s, key=lambda k: est.wall_terms_s[k])
    if term in _ONE_KEY_TERMS:
        key, fix = _ONE_KEY_TERMS[term]
        return _blame(_longer(s), _below(s, key)), _one_key_work(term, s, est), fix
    key = _blame(_longer(s), *_rates(s))
    rate = est.service_steps / t
    what = (
        f"{_cause(s, key, rate, 'service periods', est.service_steps)} "
        f"(~{SERVICE_STEP_S[s.runtime.kind] * 1e3:g} ms each)"
    )
    return key, what, "shorten run.max_time_s or lengthen the services' periods"


def _one_key_work(term: str, s: Scenario, est: Estimate) -> str:
    """What the key of a one-key term makes over the run, in an error's words."""
    t = s.run.max_time_s
    if term == "rk4":
        per_period = s.vehicle.period_s / s.vehicle.dt_internal_s
        return (
            f"vehicle.dt_internal_s={s.vehicle.dt_internal_s:g} over run.max_time_s={t:g} is "
            f"{est.rk4_steps:.3g} RK4 steps ({per_period:.3g} a vehicle period, "
            f"~{RK4_STEP_S * 1e6:g} µs each)"
        )
    if term == "predict":
        return (
            f"estimator.max_predict_dt_s={s.estimator.max_predict_dt_s:g} over "
            f"run.max_time_s={t:g} is {est.predict_steps:.3g} prediction sub-steps"
        )
    return f"a realtime run of run.max_time_s={t:g} at runtime.time_scale={s.runtime.time_scale:g}"


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
        _below(s, "vehicle.period_s"),
        ("sensor.nav_rate_hz", s.sensor.nav_rate_hz / sensor.nav_rate_hz),
        ("sensor.obstacle_rate_hz", s.sensor.obstacle_rate_hz / sensor.obstacle_rate_hz),
        _below(s, "estimator.period_s"),
        _below(s, "planner.period_s"),
        _below(s, "runtime.stats_period_s"),
    ]


def _below(s: Scenario, key: str) -> tuple[str, float]:
    """(key, _ratio_below of its value) for a dotted scenario key."""
    section, name = key.split(".")
    return key, _ratio_below(getattr(s, section), name)


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
