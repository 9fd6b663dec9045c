"""The mission registry: a scenario names a registered mission, never code to import."""

from __future__ import annotations

import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

from common.config.errors import ConfigError, ConfigValueError
from common.config.missions import (
    MISSIONS,
    MISSIONS_ENV,
    add_mission,
    parse_missions,
    registered_missions,
    resolve_mission,
)
from common.config.run import RunConfig
from common.config.scenario import Scenario
from common.runtime.model import mission as mission_module
from common.runtime.model.mission import load_mission

REPO = Path(__file__).resolve().parents[1]

# A module that leaves a file behind the moment anything imports it.
TRIPWIRE = """\
from pathlib import Path
Path(__file__).with_name("imported.flag").write_text("imported")


class Boom:
    def __init__(self, scenario):
        Path(__file__).with_name("called.flag").write_text("called")
"""


def test_the_registry_holds_the_built_in_mission_and_the_one_the_tests_register() -> None:
    registry = registered_missions()
    assert registry == {
        "auv": "services.mission:AuvMission",
        "testloop": "tests.helpers.testloop:TestLoop",
    }
    assert dict(MISSIONS) == {"auv": "services.mission:AuvMission"}


def test_pyproject_registers_no_mission_and_a_bare_environment_knows_only_the_built_in(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    # a built wheel holds no tests/: nothing in its metadata may name them
    project = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]
    assert "entry-points" not in project
    monkeypatch.delenv(MISSIONS_ENV)
    assert registered_missions() == {"auv": "services.mission:AuvMission"}
    with pytest.raises(ConfigValueError, match=r"'testloop' is not a registered mission"):
        RunConfig(mission="testloop")


def test_the_environment_adds_missions_by_name_and_keeps_those_it_had() -> None:
    value = add_mission("a=pkg.a:A", "b", "pkg.b:B")
    assert value == "a=pkg.a:A,b=pkg.b:B"
    assert parse_missions(value) == {"a": "pkg.a:A", "b": "pkg.b:B"}
    assert parse_missions(" a = pkg.a:A , ") == {"a": "pkg.a:A"}
    assert parse_missions("") == {}


@pytest.mark.parametrize("value", ["pkg.a:A", "a=pkg.a", "=pkg.a:A", "auv=pkg.a:A"])
def test_a_malformed_environment_entry_says_which_and_what_is_expected(
    monkeypatch: pytest.MonkeyPatch, value: str
) -> None:
    monkeypatch.setenv(MISSIONS_ENV, value)
    with pytest.raises(ConfigError, match=rf"^{MISSIONS_ENV}: '{value}' is no mission entry"):
        registered_missions()


def test_the_default_mission_is_the_auv_by_its_registered_name() -> None:
    assert RunConfig().mission == "auv"
    assert resolve_mission(RunConfig().mission) == ("auv", "services.mission:AuvMission")


@pytest.mark.parametrize(
    ("spelling", "name"),
    [
        ("auv", "auv"),
        ("services.mission:AuvMission", "auv"),  # scenarios written before the registry
        ("testloop", "testloop"),
        ("tests.helpers.testloop:TestLoop", "testloop"),
    ],
)
def test_a_name_or_its_registered_target_names_the_mission(spelling: str, name: str) -> None:
    run = RunConfig(mission=spelling)
    assert run.mission_name == name
    flow = load_mission(Scenario(run=run)).dataflow
    expected = {"auv": "estimator", "testloop": "filter"}[name]
    assert expected in flow.names


def test_an_unregistered_mission_is_refused_without_importing_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    (tmp_path / "tripwire_mission.py").write_text(TRIPWIRE)
    monkeypatch.syspath_prepend(str(tmp_path))
    with pytest.raises(ConfigValueError) as info:
        RunConfig(mission="tripwire_mission:Boom")
    assert info.value.key_path == ("mission",)
    problem = info.value.problem
    assert problem.startswith("'tripwire_mission:Boom' is not a registered mission")
    assert "'auv' (services.mission:AuvMission)" in problem
    assert "'testloop' (tests.helpers.testloop:TestLoop)" in problem
    assert "tripwire_mission" not in sys.modules
    assert not (tmp_path / "imported.flag").exists()


def test_load_mission_refuses_a_forged_value_too(tmp_path: Path) -> None:
    run = RunConfig()
    object.__setattr__(run, "mission", "os:getcwd")  # a Scenario not built by the loader
    with pytest.raises(ConfigError, match=r"^run\.mission: 'os:getcwd' is not a registered"):
        load_mission(Scenario(run=run))


def test_a_registered_mission_that_cannot_be_imported_says_which(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(
        mission_module, "resolve_mission", lambda _: ("ghost", "no_such_pkg_xyz.ghost:Ghost")
    )
    with pytest.raises(ValueError, match=r"registered mission 'ghost' \(no_such_pkg_xyz"):
        load_mission(Scenario())


# --- `tidelink check`, as a user runs it ---------------------------------------------------------


def _check(path: Path, *args: str, pythonpath: str = "") -> subprocess.CompletedProcess[str]:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (pythonpath, str(REPO)) if p))
    return subprocess.run(
        [sys.executable, "-m", "services.cli", "check", str(path), *args],
        capture_output=True,
        text=True,
        timeout=60,
        cwd=REPO,
        env=env,
        check=False,
    )


@pytest.mark.parametrize("mission", ["os:getcwd", "subprocess:call", "tripwire_mission:Boom"])
def test_check_exits_2_naming_the_registered_missions_and_imports_nothing(
    tmp_path: Path, mission: str
) -> None:
    plugin_dir = tmp_path / "plugins"
    plugin_dir.mkdir()
    (plugin_dir / "tripwire_mission.py").write_text(TRIPWIRE)
    scenario = tmp_path / "s.toml"
    scenario.write_text(f'[run]\nmission = "{mission}"\n')
    res = _check(scenario, pythonpath=str(plugin_dir))
    assert res.returncode == 2, res.stderr
    assert res.stdout == ""
    assert f"{scenario}: run.mission: '{mission}' is not a registered mission" in res.stderr
    assert "'auv' (services.mission:AuvMission)" in res.stderr
    assert "'testloop' (tests.helpers.testloop:TestLoop)" in res.stderr
    assert sorted(p.name for p in plugin_dir.iterdir()) == ["tripwire_mission.py"]


def test_check_accepts_the_old_spelling_of_the_default_mission() -> None:
    old = 'run.mission="services.mission:AuvMission"'
    res = _check(REPO / "configs/default.toml", "--set", old)
    assert res.returncode == 0, res.stderr
    assert "OK (mission auv, services estimator, planner, sensor, vehicle)" in res.stdout
