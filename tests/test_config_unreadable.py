"""Every config that cannot be read exits 2 naming what is wrong: the file (binary, UTF-16,
nested too deeply, a directory) or the flag (--restart, --set, --seed), never blaming the file
for what a flag said."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest
from helpers.launch_proc import REPO, tidelink_check, tidelink_cli

from common.config.loader import ConfigError, read_toml
from common.config.scenario import load_scenario

DEFAULT = REPO / "configs" / "default.toml"


def _binary(path: Path) -> Path:
    path.write_bytes(bytes(range(256)) * 4)
    return path


def _utf16(path: Path) -> Path:
    path.write_text(DEFAULT.read_text(), encoding="utf-16")  # with a byte-order mark
    return path


def _deep(path: Path) -> Path:
    path.write_text("a = " + "[" * 5000 + "]" * 5000 + "\n")
    return path


def _deep_tables(path: Path) -> Path:
    path.write_text("a = " + "{b = " * 5000 + "1" + "}" * 5000 + "\n")
    return path


def _directory(path: Path) -> Path:
    path.mkdir()
    return path


UNREADABLE: dict[str, tuple[Callable[[Path], Path], str]] = {
    "binary": (_binary, "is a binary file, not a TOML file"),
    "utf16": (_utf16, "is UTF-16 text, but a TOML file must be UTF-8"),
    "deep_arrays": (_deep, "arrays or tables nested too deeply"),
    "deep_tables": (_deep_tables, "arrays or tables nested too deeply"),
    "directory": (_directory, "is a directory, not a TOML file"),
}


@pytest.mark.parametrize("kind", sorted(UNREADABLE))
def test_an_unreadable_file_is_a_config_error_naming_it(tmp_path: Path, kind: str) -> None:
    make, words = UNREADABLE[kind]
    path = make(tmp_path / "scenario.toml")
    with pytest.raises(ConfigError) as info:
        read_toml(path)
    assert info.value.file == str(path) and words in info.value.problem


@pytest.mark.parametrize("kind", ["binary", "utf16", "deep_arrays", "directory"])
def test_check_exits_2_naming_an_unreadable_file(tmp_path: Path, kind: str) -> None:
    make, words = UNREADABLE[kind]
    path = make(tmp_path / "scenario.toml")
    res = tidelink_check(str(path))
    assert res.returncode == 2, res.stderr
    assert f"tidelink: config error: {path}: {words}" in res.stderr
    assert "Traceback" not in res.stderr


def test_an_unknown_set_key_is_blamed_on_set_not_the_file() -> None:
    for override, key in (("planner.nosuch=1", "planner.nosuch"), ("nosuch.x=1", "nosuch")):
        with pytest.raises(ConfigError) as info:
            load_scenario(DEFAULT, [override])
        assert (info.value.file, info.value.key) == ("--set", key)
        assert "unknown key" in info.value.problem
    with pytest.raises(ConfigError) as info:
        load_scenario(DEFAULT, ["run=1"])
    assert (info.value.file, info.value.key) == ("--set", "run")
    with pytest.raises(ConfigError) as info:
        load_scenario(DEFAULT, seed=-1)
    assert (info.value.file, info.value.key) == ("--seed", "run.seed")


def test_an_error_of_the_file_stays_the_files_beside_a_good_set(tmp_path: Path) -> None:
    path = tmp_path / "scenario.toml"
    path.write_text(DEFAULT.read_text().replace("[sensor]", "[sensor]\nnosuch = 1", 1))
    with pytest.raises(ConfigError) as info:
        load_scenario(path, ["planner.rho0_m=2.0", "sensor.nav_rate_hz=5.0"])
    assert (info.value.file, info.value.key) == (str(path), "sensor.nosuch")


def test_the_cli_says_a_bad_set_key_came_from_set() -> None:
    res = tidelink_check(str(DEFAULT), "--set", "planner.nosuch=1")
    assert res.returncode == 2, res.stderr
    assert "tidelink: config error: --set: planner.nosuch: unknown key" in res.stderr
    assert str(DEFAULT) not in res.stderr and "default.toml" not in res.stderr


def test_a_bad_restart_policy_exits_2_naming_the_flag(tmp_path: Path) -> None:
    # refused before any process starts: the launch never gets to its router
    res = tidelink_cli(
        "launch", str(DEFAULT), "--restart", "planner=sometimes", "--out", str(tmp_path / "x")
    )
    assert res.returncode == 2, res.stderr
    assert (
        "tidelink: config error: --restart: 'planner=sometimes': mode 'sometimes', expected "
        "one of never, on-failure, always"
    ) in res.stderr
    assert not (tmp_path / "x").exists()
