"""The work budget: estimates match what the code allocates, and too much work is refused."""

from __future__ import annotations

import dataclasses
import math
import subprocess
import tracemalloc
from pathlib import Path

import numpy as np
import pytest
from helpers.launch_proc import tidelink_cli
from helpers.planner_world import default_obstacles, default_start_goal

from common.config.budget import DEFAULT_BUDGET, check_budget
from common.config.loader import ConfigError
from common.config.planner import PlannerConfig
from common.config.scenario import Scenario, load_scenario
from common.config.work import estimate, message_rate_hz
from common.config.world import AreaConfig
from common.messages import decode, encode
from common.runtime.model.inproc import run_inproc
from common.runtime.model.record import Record
from common.world.check import check_scenario
from services.experiments.sweep.grid import expand
from services.experiments.sweep.schema import load_experiment
from services.planner.geometry.clearance import StaticField
from services.planner.plan import PlanRequest, plan_path
from services.planner.search.costmap import build_costmap
from services.planner.search.graph import _structure
from tests.helpers.scripts import load_script

REPO = Path(__file__).resolve().parents[1]
DEFAULT = REPO / "configs" / "default.toml"
SMALL = REPO / "configs" / "experiments" / "scenarios" / "small.toml"


def _scenario(*overrides: str) -> Scenario:
    return load_scenario(DEFAULT, list(overrides))[0]


# --- the estimates against the real data structures ---------------------------------------------


@pytest.mark.parametrize(
    ("x_max", "y_max", "res"), [(100.0, 40.0, 0.5), (10.2, 4.0, 0.5), (37.0, 11.0, 0.3)]
)
def test_the_grid_estimate_is_the_cost_maps_shape(x_max: float, y_max: float, res: float) -> None:
    s = _scenario(f"world.area.x_max_m={x_max}", f"world.area.y_max_m={y_max}",
                  f"planner.resolution_m={res}", "world.goal.x_m=5.0", "world.goal.y_m=3.0",
                  "world.start.x_m=2.0", "world.start.y_m=2.0", "world.circles=[]",
                  "world.polygons=[]", "world.moving=[]")  # fmt: skip
    cmap = build_costmap(s.world.area, StaticField.build((), ()), np.zeros((0, 3)), 0.8, s.planner)
    assert cmap.cost.shape == cmap.blocked.shape == (cmap.ny, cmap.nx)
    assert estimate(s).grid_cells == cmap.cost.size


@pytest.mark.parametrize(
    ("search", "connectivity", "res"),
    [("dijkstra", 8, 0.25), ("dijkstra", 16, 0.25), ("astar", 8, 0.5)],
)
def test_a_replans_peak_memory_is_what_the_budget_estimates(
    search: str, connectivity: int, res: float
) -> None:
    cfg = PlannerConfig(resolution_m=res, connectivity=connectivity, search=search)
    start, goal = default_start_goal()
    req = PlanRequest(start=start, goal=goal, area=AreaConfig(), obstacles=default_obstacles(),
                      vehicle_radius_m=0.8, r_min_m=5.0, v_ref_mps=1.5)  # fmt: skip
    s = dataclasses.replace(Scenario(), planner=cfg)
    _structure.cache_clear()  # the first replan on a grid builds its graph structure too
    tracemalloc.start()
    try:
        assert plan_path(req, cfg).ok
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    est = estimate(s).planner_bytes
    # the estimate is the process's resident growth (scripts/bench_budget.py): a little above
    # what Python's allocator traces, never below it
    assert 0.8 * est <= peak <= est, (peak, est)


def test_the_record_estimate_is_the_messages_a_run_keeps() -> None:
    s = _scenario('runtime.kind="inproc"', "run.max_time_s=10")
    record = run_inproc(s).record
    est = estimate(s)
    assert est.messages == pytest.approx(10.0 * message_rate_hz(s))
    # a few more: both ends of the run publish (and the final stats); fewer: empty scans
    assert 0.9 * est.messages <= record.count <= 1.02 * est.messages
    # what the record holds per message: decoded structs in their dicts, as the runtime keeps
    copies = [(k, decode(encode(m))) for k in record.keys() for m in record.stream(*k)]
    tracemalloc.start()
    try:
        kept = Record()
        for (service, stream), msg in copies:
            kept.add(service, stream, decode(encode(msg)))
        size, _ = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    # the commands' sequences (10 s ahead by default) are most of it: estimated per entry
    assert est.sequence_entries > 0
    assert 0.7 * est.record_bytes <= size <= 1.3 * est.record_bytes


def test_the_shipped_scenarios_are_well_inside_the_budget() -> None:
    for path in [*sorted((REPO / "configs").glob("*.toml")), SMALL]:
        s, _ = load_scenario(path, check=check_scenario)
        est = estimate(s)
        n = max(1, len(s.vehicles))  # a fleet: each vehicle's share
        assert est.planner_bytes < DEFAULT_BUDGET.planner_bytes / 100
        assert est.record_bytes / n < DEFAULT_BUDGET.record_bytes / 10
        assert est.wall_s / n < DEFAULT_BUDGET.wall_s / 10


# --- too much work is refused, naming the key, the estimate and the budget ------------------------


@pytest.mark.parametrize(
    ("overrides", "key", "needles"),
    [
        (
            ["planner.resolution_m=0.001"],
            "planner.resolution_m",
            ["planner.resolution_m=0.001 over a 100 m × 40 m area is a 4e+09-cell cost map",
             "(~894 GiB at a replan's peak", "the budget is 4.47e+06 cells (~1 GiB)",
             "coarsen the resolution or shrink world.area"],
        ),
        (
            ["world.area.x_max_m=10000", "world.area.y_max_m=10000"],
            "world.area",
            ["world.area of 10000 m × 10000 m at planner.resolution_m=0.5 is a 4e+08-cell"],
        ),
        (
            ['planner.search="astar"', "planner.connectivity=16", "planner.resolution_m=0.05"],
            "planner.resolution_m",
            ["1.6e+06-cell cost map", "1844 B a cell with astar and 16 neighbours",
             "the budget is 5.82e+05 cells"],
        ),
        (
            ["run.max_time_s=1e9"],
            "run.max_time_s",
            ["run.max_time_s=1e+09 at 86 messages a mission second is 8.6e+10 messages",
             "kept in the run's record", "the budget is 1 GiB: shorten",
             "entries of the commands' sequences: controller.sequence.horizon_s"],
        ),
        (
            ["runtime.stats_period_s=1e-4"],
            "runtime.stats_period_s",
            ["runtime.stats_period_s=0.0001 makes 4.01e+04 messages a mission second"],
        ),
        (
            ["vehicle.dt_internal_s=1e-7"],
            "vehicle.dt_internal_s",
            ["vehicle.dt_internal_s=1e-07 over run.max_time_s=200 is 2e+09 RK4 steps "
             "(5e+05 a vehicle period", "the run would take ~7.", "the budget is 1 h"],
        ),
        (
            ["estimator.max_predict_dt_s=1e-6"],
            "estimator.max_predict_dt_s",
            ["estimator.max_predict_dt_s=1e-06 over run.max_time_s=200 is 5", "sub-steps"],
        ),
        (
            ['runtime.kind="realtime"', "runtime.time_scale=1", "run.max_time_s=3900"],
            "run.max_time_s",
            ["a realtime run of run.max_time_s=3900 at runtime.time_scale=1",
             "the run would take ~1.08 h"],
        ),
    ],
)  # fmt: skip
def test_too_much_work_is_a_config_error_naming_key_estimate_and_budget(
    overrides: list[str], key: str, needles: list[str]
) -> None:
    with pytest.raises(ConfigError) as info:
        load_scenario(DEFAULT, overrides, check=check_scenario)
    err = info.value
    # a key the overrides set is blamed on --set, the file's own on the file
    assert err.file == (
        "--set" if any(o.startswith(key + "=") for o in overrides) else str(DEFAULT)
    )
    assert err.key == key, err
    for needle in needles:
        assert needle in err.problem, f"{needle!r} not in {err.problem!r}"
    assert err.problem.endswith("--budget FACTOR allows FACTOR times every budget")


def test_the_wall_budget_names_the_run_length_when_service_periods_dominate() -> None:
    # at the default rates the record's budget binds first (every period publishes); without
    # it, a long lockstep run is refused for its wall time
    s = _scenario("run.max_time_s=1e6")
    with pytest.raises(ConfigError) as info:
        check_budget(s, budget=dataclasses.replace(DEFAULT_BUDGET, record_bytes=math.inf))
    assert info.value.key == "run.max_time_s"
    assert info.value.problem.startswith(
        "run.max_time_s=1e+06 at 54 service periods a mission second is 5.4e+07 service periods "
        "(~1.3 ms each): the run would take ~20.1 h of wall time (lockstep: service periods ~19.5 h"
    )


def test_a_scaled_budget_admits_what_the_default_refuses() -> None:
    s = _scenario("planner.resolution_m=0.01")  # 4e7 cells, ~10 GiB at a replan's peak
    with pytest.raises(ConfigError, match="planner.resolution_m=0.01 over"):
        check_budget(s)
    check_budget(s, budget=DEFAULT_BUDGET.scaled(10.0))


# --- every command that runs a scenario checks it first ---------------------------------------


def _tidelink(*args: str) -> subprocess.CompletedProcess[str]:
    return tidelink_cli(*args, timeout_s=120.0)


def test_check_prints_the_estimate_and_takes_a_budget_factor() -> None:
    ok = _tidelink("check", str(DEFAULT))
    assert ok.returncode == 0, ok.stderr
    assert "estimated: planner grid 1.6e+04 cells (~3.66 MiB a replan)" in ok.stdout
    fine = "planner.resolution_m=0.01"
    refused = _tidelink("check", str(DEFAULT), "--set", fine)
    assert refused.returncode == 2
    assert "--set: planner.resolution_m: planner.resolution_m=0.01 over" in refused.stderr
    allowed = _tidelink("check", str(DEFAULT), "--set", fine, "--budget", "10")
    assert allowed.returncode == 0, allowed.stderr
    bad = _tidelink("check", str(DEFAULT), "--budget", "0")
    assert bad.returncode == 2
    assert "'0' is not a factor > 0" in bad.stderr


@pytest.mark.parametrize("command", ["run", "launch"])
def test_run_and_launch_refuse_before_anything_starts(command: str, tmp_path: Path) -> None:
    out = tmp_path / "out"
    res = _tidelink(command, str(DEFAULT), "--set", "vehicle.dt_internal_s=1e-7", "--out", str(out))
    assert res.returncode == 2
    assert "vehicle.dt_internal_s: vehicle.dt_internal_s=1e-07 over" in res.stderr
    assert not out.exists()


def test_a_sweep_checks_every_cell_against_the_budget_before_it_starts(tmp_path: Path) -> None:
    p = tmp_path / "exp.toml"
    p.write_text(
        f'name = "t"\nscenario = "{SMALL}"\ncontrollers = ["nurbs"]\n'
        '[[axes]]\nname = "size"\n'
        '[[axes.values]]\nlabel = "small"\n'
        '[[axes.values]]\nlabel = "huge"\n'
        'set = { "world.area.x_max_m" = 20000.0, "world.area.y_max_m" = 20000.0 }\n'
    )
    exp = load_experiment(p)
    with pytest.raises(ConfigError) as info:
        expand(exp, str(p), runtime="inproc")
    msg = str(info.value)
    where = "axes[0].values[1].set.world.area.y_max_m: in cell size=huge|controller=nurbs:"
    assert msg.startswith(f"{p}: {where}")
    assert "scenario key world.area: world.area of 20000 m × 20000 m at planner.resolution_m" in msg
    big = expand(exp, str(p), runtime="inproc", budget=DEFAULT_BUDGET.scaled(1e4))
    assert [r.labels["size"] for r in big.runs] == ["small"] * exp.seeds + ["huge"] * exp.seeds


@pytest.mark.heavy
def test_the_budget_benchmark_measures_replans_near_the_estimate(
    capsys: pytest.CaptureFixture[str],
) -> None:
    bench = load_script("bench_budget")
    rows = bench.bench_replans([0.25], [("dijkstra", 8), ("dijkstra", 16)])
    # each replan in a fresh process: its resident growth is the estimate, within 15 %
    assert [(r[0], r[1]) for r in rows] == [("dijkstra", 8), ("dijkstra", 16)]
    assert all(0.85 <= r[3] <= 1.15 for r in rows), rows
    bench.bench_runs(2.0)
    assert "inproc runs of the default mission" in capsys.readouterr().out
