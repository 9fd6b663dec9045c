"""Scenario loading: errors name the file, the key path and the expectation; overrides; `check`."""

from __future__ import annotations

import json
import pickle
import subprocess
import sys
from pathlib import Path

import pytest
from helpers.launch_proc import tidelink_check

from common.config.errors import ConfigValueError
from common.config.loader import ConfigError
from common.config.network import LinkProfile
from common.config.scenario import load_scenario
from common.world.check import check_scenario
from services.experiments.sweep.grid import expand
from services.experiments.sweep.schema import load_experiment

REPO = Path(__file__).resolve().parents[1]

GOOD = """\
[run]
name = "cfgtest"
mission = "testloop"
max_time_s = 2.0
seed = 7

[bus]
listen = ["tcp/127.0.0.1:7447"]

[network.default]
delay_s = 0.05
jitter = "normal"
jitter_s = 0.01

[[network.links]]
link = "sensor/nav->filter"
profile = { loss = "bernoulli", loss_p = 0.25 }

[[network.outages]]
service = "ctrl"
start_s = 1.0
end_s = 1.5
"""


def _write(tmp_path: Path, text: str, name: str = "scenario.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _error(path: Path, overrides: list[str] | None = None) -> ConfigError:
    with pytest.raises(ConfigError) as info:
        load_scenario(path, overrides, check=check_scenario)
    return info.value


def test_a_good_file_loads_into_the_dataclasses(tmp_path: Path) -> None:
    scenario, raw = load_scenario(_write(tmp_path, GOOD))
    assert scenario.run.name == "cfgtest"
    assert scenario.run.seed == 7
    assert scenario.run.max_time_s == 2.0
    assert scenario.bus.listen == ("tcp/127.0.0.1:7447",)
    assert scenario.network.default.delay_s == 0.05
    assert scenario.network.default.jitter == "normal"
    assert scenario.network.links[0].profile.loss_p == 0.25
    assert scenario.network.outages[0].service == "ctrl"
    assert (scenario.network.outages[0].start_s, scenario.network.outages[0].end_s) == (1.0, 1.5)
    # an absent section takes its defaults
    assert scenario.runtime.kind == "inproc"
    assert raw["run"]["name"] == "cfgtest"


@pytest.mark.parametrize(
    ("text", "key", "needles"),
    [
        pytest.param(
            GOOD.replace("seed = 7", "sede = 7"),
            "run.sede",
            ["unknown key", "known keys:", "seed"],
            id="unknown key",
        ),
        pytest.param(
            GOOD + "\n[planet]\nx = 1\n", "planet", ["unknown key", "network"], id="unknown section"
        ),
        pytest.param(
            GOOD.replace("seed = 7", 'seed = "seven"'),
            "run.seed",
            ["expected an integer", "got a string"],
            id="wrong type",
        ),
        pytest.param(
            GOOD.replace("delay_s = 0.05", 'delay_s = "fast"'),
            "network.default.delay_s",
            ["expected a number", "got a string"],
            id="wrong type nested",
        ),
        pytest.param(
            GOOD.replace('listen = ["tcp/127.0.0.1:7447"]', 'listen = "tcp/127.0.0.1:7447"'),
            "bus.listen",
            ["expected an array", "got a string"],
            id="scalar for array",
        ),
        pytest.param(
            GOOD.replace('jitter = "normal"', 'jitter = "gauss"'),
            "network.default.jitter",
            ["'gauss' is not one of", "'normal'", "'pareto'"],
            id="not a literal",
        ),
        pytest.param(
            GOOD.replace("delay_s = 0.05", "delay_s = -0.05"),
            "network.default.delay_s",
            ["-0.05", "expected a finite value >= 0"],
            id="out of range",
        ),
        pytest.param(
            GOOD.replace("loss_p = 0.25", "loss_p = 1.5"),
            "network.links[0].profile.loss_p",
            ["1.5", "not a probability", "[0, 1]"],
            id="out of range in array of tables",
        ),
        pytest.param(
            GOOD.replace("max_time_s = 2.0", "max_time_s = nan"),
            "run.max_time_s",
            ["expected a finite number"],
            id="nan",
        ),
        pytest.param(
            GOOD.replace('jitter = "normal"', 'jitter = "uniform"').replace(
                "jitter_s = 0.01", "jitter_s = 0.2"
            ),
            "network.default.jitter_s",
            ["0.2", "exceeds delay_s 0.05", "expected jitter_s <= delay_s"],
            id="inconsistent: uniform jitter wider than the delay",
        ),
        pytest.param(
            GOOD.replace("end_s = 1.5", "end_s = 0.5"),
            "network.outages[0].end_s",
            ["0.5", "expected end_s > start_s (1.0)"],
            id="inconsistent: outage ends before it starts",
        ),
        pytest.param(
            GOOD.replace("[bus]", '[bus]\nmode = "client"').replace(
                'listen = ["tcp/127.0.0.1:7447"]', ""
            ),
            "bus.connect",
            ["a client must connect to at least one router endpoint"],
            id="inconsistent: client without connect",
        ),
        pytest.param(
            GOOD.replace("start_s = 1.0\n", ""),
            "network.outages[0].start_s",
            ["required key is missing"],
            id="missing required key",
        ),
    ],
)
def test_errors_name_the_file_the_key_and_the_expectation(
    tmp_path: Path, text: str, key: str, needles: list[str]
) -> None:
    path = _write(tmp_path, text)
    err = _error(path)
    assert err.file == str(path)
    assert err.key == key
    message = str(err)
    assert message.startswith(f"{path}: {key}: "), message
    for needle in needles:
        assert needle in err.problem, f"{needle!r} not in {err.problem!r}"


def test_a_missing_file_is_named(tmp_path: Path) -> None:
    path = tmp_path / "nowhere.toml"
    err = _error(path)
    assert err.file == str(path)
    assert "file not found" in err.problem
    assert str(path) in str(err)


def test_bad_toml_is_named_with_the_parser_position(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD.replace("seed = 7", "seed = = 7"))
    err = _error(path)
    assert err.file == str(path)
    assert "not valid TOML" in err.problem
    assert "line 5" in err.problem  # tomllib's position of the broken line


def test_overrides_set_nested_keys_and_are_validated(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD)
    scenario, raw = load_scenario(
        path,
        [
            "network.default.delay_s=0.2",
            'runtime.kind="lockstep"',
            "runtime.time_scale=5",  # an integer for a float field is accepted as a number
            "run.name=bare_word",  # not TOML: taken as a string
            "bus.multicast_scouting=true",
        ],
        seed=42,
    )
    assert scenario.network.default.delay_s == 0.2
    assert scenario.runtime.kind == "lockstep"
    assert scenario.runtime.time_scale == 5.0
    assert scenario.run.name == "bare_word"
    assert scenario.bus.multicast_scouting is True
    assert scenario.run.seed == 42
    assert raw["network"]["default"]["delay_s"] == 0.2  # the raw data carries the overrides


def test_an_override_creates_a_missing_section(tmp_path: Path) -> None:
    path = _write(tmp_path, '[run]\nmission = "testloop"\n')
    scenario, _ = load_scenario(path, ["runtime.stats_period_s=0.5"])
    assert scenario.runtime.stats_period_s == 0.5


@pytest.mark.parametrize(
    ("override", "key", "needle"),
    [
        ("network.default.delay_s=-1", "network.default.delay_s", "expected a finite value >= 0"),
        ("run.bogus=1", "run.bogus", "unknown key"),
        ("runtime.kind=warp", "runtime.kind", "'warp' is not one of"),
        ("bus.lease_s=0", "bus.lease_s", "must be 0.1 to 3600 s"),
        # command sequences (issue 16): what the vehicle would refuse is a config error
        ("controller.sequence.horizon_s=-1", "controller.sequence.horizon_s", ">= 0"),
        ("controller.jitter_margin_k=-0.5", "controller.jitter_margin_k", ">= 0"),
        ("planner.delay_window=0", "planner.delay_window", "[1, 10000]"),
        (
            "controller.sequence.horizon_s=25.0",
            "controller.sequence.horizon_s",
            "250 entries at planner.period_s 0.1, more than the vehicle accepts "
            "(vehicle.watchdog.max_sequence_len = 200)",
        ),
        (
            "vehicle.watchdog.max_horizon_s=5.0",
            "controller.sequence.horizon_s",
            "further than the vehicle accepts (vehicle.watchdog.max_horizon_s = 5.0)",
        ),
        ("planner.period_s=0.1005", "planner.period_s", "no whole number of milliseconds"),
        (
            "controller.sequence.horizon_s=4.0",
            "controller.sequence.horizon_s",
            "shorter than the stop tail needs to brake from cruise",
        ),
    ],
)
def test_bad_overrides_are_reported_at_their_key(
    tmp_path: Path, override: str, key: str, needle: str
) -> None:
    err = _error(_write(tmp_path, GOOD), [override])
    assert err.key == key
    assert needle in err.problem


def test_single_commands_need_no_whole_millisecond_period(tmp_path: Path) -> None:
    # without sequences (horizon 0, the ablation) the period is free, as it always was
    path = _write(tmp_path, GOOD)
    scenario, _ = load_scenario(
        path, ["planner.period_s=0.1005", "controller.sequence.horizon_s=0"], check=check_scenario
    )
    assert scenario.controller.sequence.entries(scenario.planner.period_s) == 0


@pytest.mark.parametrize(
    ("key", "value", "needle"),
    [
        ("controller.compensate_baselines", "true", "the same for every controller"),
        ("controller.fuzzy_pid.slow_k", "1.0", "not from the immune fuzzy PID literature"),
        ("controller.fuzzy_pid.v_floor_ratio", "0.4", "shared speed profile"),
        ("controller.nurbs.curvature_budget", "0.7", "controller.speed.curvature_budget"),
        ("controller.nurbs.preview_s", "3.0", "controller.speed.preview_s"),
    ],
)
def test_a_removed_key_says_it_was_removed_and_why(
    tmp_path: Path, key: str, value: str, needle: str
) -> None:
    # in the file and as an override alike: not a bare "unknown key", but the reason
    table, _, name = key.rpartition(".")
    for path, overrides in (
        (_write(tmp_path, f"{GOOD}\n[{table}]\n{name} = {value}\n", "in_file.toml"), []),
        (_write(tmp_path, GOOD, "plain.toml"), [f"{key}={value}"]),
    ):
        err = _error(path, overrides)
        assert err.key == key
        assert err.problem.startswith("was removed: ") and needle in err.problem


def test_an_override_without_a_value_is_rejected(tmp_path: Path) -> None:
    err = _error(_write(tmp_path, GOOD), ["run.seed"])
    assert err.file == "--set"
    assert "expected key.path=value" in err.problem


def test_an_override_into_a_scalar_is_rejected(tmp_path: Path) -> None:
    err = _error(_write(tmp_path, GOOD), ["run.seed.low=1"])
    assert err.file == "--set"
    assert err.key == "run.seed.low"
    assert "seed is not a table" in err.problem


# --- key paths are data, not text --------------------------------------------------------------


def test_a_nested_error_carries_its_key_path(tmp_path: Path) -> None:
    err = _error(_write(tmp_path, GOOD.replace("loss_p = 0.25", "loss_p = 1.5")))
    assert err.key_path == ("network", "links", 0, "profile", "loss_p")
    assert err.problem == "1.5 is not a probability, expected a value in [0, 1]"


def test_a_post_init_error_below_a_field_carries_the_whole_path(tmp_path: Path) -> None:
    # WorldConfig.__post_init__ names the polygon and its field; the loader prefixes "world"
    text = GOOD + "\n[[world.polygons]]\nid = 1\nvertices_m = [10, 10, 12, 10, 200, 12]\n"
    err = _error(_write(tmp_path, text))
    assert err.key_path == ("world", "polygons", 0, "vertices_m")
    assert str(err).endswith(": world.polygons[0].vertices_m: a vertex lies outside the area")


def test_a_post_init_range_error_names_its_field_as_data() -> None:
    with pytest.raises(ConfigValueError) as info:
        LinkProfile(delay_s=-0.5)
    assert info.value.key_path == ("delay_s",)
    assert info.value.problem == "-0.5 is invalid, expected a finite value >= 0"
    assert str(info.value) == "delay_s: -0.5 is invalid, expected a finite value >= 0"


@pytest.mark.parametrize(
    ("world", "key_path", "needle"),
    [
        pytest.param(
            "[[world.polygons]]\nid = 1\nvertices_m = [40, 10, 44, 14, 44, 10, 40, 14]\n",
            ("world", "polygons", 0, "vertices_m"),
            "edges cross each other, expected a simple polygon",
            id="bow tie",
        ),
        pytest.param(
            "[[world.polygons]]\nid = 1\nvertices_m = [40, 10, 42, 12, 44, 14]\n",
            ("world", "polygons", 0, "vertices_m"),
            "the polygon has zero area",
            id="flat polygon",
        ),
        pytest.param(
            "[[world.circles]]\nid = 1\nx_m = 6.0\ny_m = 20.0\nradius_m = 2.0\n",
            ("world", "start"),
            "(5.0, 20.0) puts the hull (radius 0.8 m, vehicle.radius_m) in contact with "
            "obstacle 1 at t = 0: clearance -1.80 m",
            id="start inside a circle",
        ),
        pytest.param(
            # the centre is 0.5 m off the circle, the 0.8 m hull overlaps it by 0.3 m
            "[[world.circles]]\nid = 3\nx_m = 8.5\ny_m = 20.0\nradius_m = 3.0\n",
            ("world", "start"),
            "in contact with obstacle 3 at t = 0: clearance -0.30 m, expected > 0",
            id="start hull touches a circle",
        ),
        pytest.param(
            "[[world.polygons]]\nid = 4\n"
            "vertices_m = [95.5, 15.0, 99.0, 15.0, 99.0, 25.0, 95.5, 25.0]\n",
            ("world", "goal"),
            "(95.0, 20.0) puts the hull (radius 0.8 m, vehicle.radius_m) in contact with "
            "obstacle 4 at t = 0: clearance -0.30 m",
            id="goal hull touches a polygon",
        ),
        pytest.param(
            '[[world.moving]]\nid = 5\nkind = "line"\nradius_m = 1.0\nx0_m = 6.0\n'
            "y0_m = 20.0\nvx_mps = 0.5\nvy_mps = 0.0\n",
            ("world", "start"),
            "in contact with obstacle 5 at t = 0: clearance -0.80 m",
            id="start hull touches a moving obstacle at t = 0",
        ),
        pytest.param(
            "[[world.circles]]\nid = 6\nx_m = 95.0\ny_m = 24.0\nradius_m = 2.5\n",
            ("world", "goal"),
            "(95.0, 20.0) is 0.70 m (hull to surface) from obstacle 6, inside the safe "
            "distance planner.rho0_m = 1 m",
            id="goal inside the planner's safe distance",
        ),
    ],
)
def test_geometry_is_checked_after_loading(
    tmp_path: Path, world: str, key_path: tuple[str | int, ...], needle: str
) -> None:
    path = _write(tmp_path, GOOD + "\n" + world)
    load_scenario(path)  # each value is fine on its own: only the geometric check rejects it
    err = _error(path)
    assert (err.file, err.key_path) == (str(path), key_path)
    assert needle in err.problem


def test_the_shipped_scenarios_pass_the_geometrictidelink_check() -> None:
    paths = sorted((REPO / "configs").glob("**/*.toml"))
    scenarios = [p for p in paths if "axes" not in p.read_text()]  # the rest are experiments
    assert len(scenarios) >= 2 and len(paths) > len(scenarios)
    for path in scenarios:
        load_scenario(path, check=check_scenario)
    # every cell of every shipped experiment is built with the same check before a sweep runs
    for path in sorted(set(paths) - set(scenarios)):
        assert expand(load_experiment(path), str(path), runtime="inproc").runs


def test_config_does_not_import_the_world() -> None:
    # common.world depends on common.config; the reverse would be a cycle. Building a world
    # with obstacles runs every world check of common.config, so a lazy import shows too.
    code = (
        "import sys, common.config.reference\n"
        "from common.config.scenario import scenario_from_raw\n"
        "w = {'polygons': [{'id': 1, 'vertices_m': [40, 10, 44, 10, 44, 14]}],\n"
        "     'circles': [{'id': 2, 'x_m': 50.0, 'y_m': 20.0, 'radius_m': 1.0}]}\n"
        "assert scenario_from_raw({'world': w}).world.polygons\n"
        "print(sorted(m for m in sys.modules if m.startswith('common.world')))"
    )
    res = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, cwd=REPO, check=True
    )
    assert res.stdout.strip() == "[]"


# --- the `tidelink check` command, as a user runs it ---------------------------------------------


def test_check_accepts_a_good_file(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD)
    res = tidelink_check(str(path))
    assert res.returncode == 0, res.stderr
    assert f"{path}: OK" in res.stdout
    assert "services ctrl, filter, plant, sensor" in res.stdout


def test_check_rejects_a_broken_file_with_the_message(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD.replace("loss_p = 0.25", "loss_p = -0.25"))
    res = tidelink_check(str(path))
    assert res.returncode != 0
    assert res.stdout == ""
    assert f"{path}: network.links[0].profile.loss_p: -0.25 is not a probability" in res.stderr


def test_check_applies_set_overrides(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD)
    res = tidelink_check(str(path), "--set", "network.default.jitter_s=-1")
    assert res.returncode != 0
    assert "network.default.jitter_s" in res.stderr
    assert "expected a finite value >= 0" in res.stderr


def test_check_rejects_a_mission_that_is_not_registered(tmp_path: Path) -> None:
    path = _write(tmp_path, GOOD.replace('mission = "testloop"', 'mission = "testloop:NoSuch"'))
    res = tidelink_check(str(path))
    assert res.returncode == 2
    assert f"{path}: run.mission: 'testloop:NoSuch' is not a registered mission" in res.stderr


def test_check_names_a_missing_file(tmp_path: Path) -> None:
    res = tidelink_check(str(tmp_path / "gone.toml"))
    assert res.returncode != 0
    assert "gone.toml" in res.stderr
    assert "file not found" in res.stderr


def test_check_reports_a_geometric_error(tmp_path: Path) -> None:
    text = GOOD + "\n[[world.circles]]\nid = 1\nx_m = 95.0\ny_m = 21.0\nradius_m = 2.0\n"
    path = _write(tmp_path, text)
    res = tidelink_check(str(path))
    assert res.returncode == 2
    assert f"{path}: world.goal: (95.0, 20.0) puts the hull" in res.stderr
    assert "in contact with obstacle 1 at t = 0: clearance -1.80 m" in res.stderr


def test_check_rejects_a_start_whose_hull_touches_an_obstacle() -> None:
    # issue 14: world.start.x_m=15.5 puts the 0.8 m hull 0.3 m into circle 1 (20, 20, r 4)
    res = tidelink_check(str(REPO / "configs" / "default.toml"), "--set", "world.start.x_m=15.5")
    assert res.returncode == 2 and res.stdout == ""
    assert (
        "configs/default.toml: world.start: (15.5, 20.0) puts the hull (radius 0.8 m, "
        "vehicle.radius_m) in contact with obstacle 1 at t = 0: clearance -0.30 m" in res.stderr
    )
    # one centimetre more and the hull is free: accepted
    ok = tidelink_check(str(REPO / "configs" / "default.toml"), "--set", "world.start.x_m=15.19")
    assert ok.returncode == 0, ok.stderr


def test_a_goal_without_a_heading_leaves_it_free_and_a_bad_one_is_named(tmp_path: Path) -> None:
    # eq. (10)'s theta_f only where the scenario gives one: a fleet entry's goal written as
    # { x_m, y_m } used to mean "arrive facing east" (a loop near the area's edge for a
    # vehicle coming from the east)
    goal = "\n[world.goal]\nx_m = 90.0\ny_m = 20.0\n"
    free = load_scenario(_write(tmp_path, GOOD + goal), check=check_scenario)
    fixed = load_scenario(_write(tmp_path, GOOD + goal), ["world.goal.theta_rad=1.5"])
    assert free[0].world.goal.theta_rad is None and fixed[0].world.goal.theta_rad == 1.5
    err = _error(_write(tmp_path, GOOD + goal), ["world.goal.theta_rad=east"])
    assert err.key == "world.goal.theta_rad" and "expected a number" in err.problem
    default = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
    assert load_scenario(default)[0].world.goal.theta_rad == 0.0


def test_the_bus_lease_is_zenohs_in_milliseconds() -> None:
    from common.bus.session import zenoh_config
    from common.config.bus import BusConfig

    assert json.loads(zenoh_config(BusConfig()).get_json("transport/link/tx/lease")) == 10_000
    short = zenoh_config(BusConfig(lease_s=2.5))
    assert json.loads(short.get_json("transport/link/tx/lease")) == 2_500


@pytest.mark.parametrize(
    "error",
    [
        ConfigError("a.toml", ("network", "links", 0, "loss_p"), "1.5 is above 1"),
        ConfigError("", "", "no key"),
        ConfigValueError(("vertices_m", 2), "not a point"),
    ],
)
def test_a_config_error_crosses_a_process_whole(error: ValueError) -> None:
    # a sweep's process pool pickles what a worker raises; the key path and problem survive
    back = pickle.loads(pickle.dumps(error))
    assert type(back) is type(error) and str(back) == str(error)
    assert back.key_path == error.key_path and back.problem == error.problem  # type: ignore[attr-defined]
