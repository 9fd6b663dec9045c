"""The command line meets users' habits: --version, Zenoh's short endpoint flags (-e, -l) on
every command with endpoints, and "did you mean" for a mistyped sub-command."""

from __future__ import annotations

import pytest

from services.cli import build_parser, main

ENDPOINT = "tcp/10.0.0.1:7447"


def test_version_names_tidelink_its_wire_format_and_zenoh(
    capsys: pytest.CaptureFixture[str],
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["--version"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    assert out.startswith("tidelink ") and "wire format v" in out and "eclipse-zenoh" in out


@pytest.mark.parametrize(
    ("typed", "meant"),
    [("lanch", "'launch'"), ("monitr", "'monitor'"), ("chek", "'check'"), ("fox", "'foxglove'")],
)
def test_a_mistyped_command_gets_a_suggestion(
    capsys: pytest.CaptureFixture[str], typed: str, meant: str
) -> None:
    with pytest.raises(SystemExit) as info:
        main(["-v", typed, "configs/default.toml"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert f"unknown command {typed!r}; did you mean {meant}?" in err


def test_an_unlike_command_is_refused_without_a_guess(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["xyzzy"])
    assert info.value.code == 2
    err = capsys.readouterr().err
    assert "unknown command 'xyzzy'" in err and "did you mean" not in err


def test_every_connect_and_listen_takes_zenohs_short_flag() -> None:
    commands = build_parser().commands
    with_connect, with_listen = set(), set()
    for name, parser in commands.items():
        text = parser.format_help()
        if "--connect" in text.replace("with --connect", ""):
            assert "-e ENDPOINT, --connect ENDPOINT" in text, name
            with_connect.add(name)
        if "--listen ENDPOINT" in text:
            assert "-l ENDPOINT, --listen ENDPOINT" in text, name
            with_listen.add(name)
    assert with_connect == {"router", "graph", "service", "monitor", "record", "replay", "foxglove"}
    assert with_listen == {"router", "launch", "replay"}


def test_the_short_flags_parse_as_the_long_ones() -> None:
    p = build_parser()
    assert p.parse_args(["monitor", "-e", ENDPOINT]).connect == ENDPOINT
    assert p.parse_args(["foxglove", "-e", ENDPOINT]).connect == ENDPOINT
    assert p.parse_args(["graph", "-e", ENDPOINT]).connect == ENDPOINT
    assert p.parse_args(["record", "-e", ENDPOINT, "-o", "x.mcap"]).connect == ENDPOINT
    a = p.parse_args(["router", "-l", "tcp/127.0.0.1:1", "-l", "tcp/127.0.0.1:2", "-e", ENDPOINT])
    assert (a.listen, a.connect) == (["tcp/127.0.0.1:1", "tcp/127.0.0.1:2"], [ENDPOINT])
    assert p.parse_args(["launch", "s.toml", "-l", ENDPOINT]).listen == [ENDPOINT]
    assert p.parse_args(["service", "planner", "s.toml", "-e", ENDPOINT]).connect == ENDPOINT
    assert p.parse_args(["replay", "r.mcap", "-l", ENDPOINT]).listen == ENDPOINT


def test_replay_takes_a_router_or_is_one_not_both(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        build_parser().parse_args(["replay", "r.mcap", "-e", ENDPOINT, "-l", ENDPOINT])
    assert info.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err
