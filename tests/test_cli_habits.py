"""The command line meets users' habits: --version, Zenoh's short endpoint flags (-e, -l) on
every command with endpoints, "did you mean" for a mistyped sub-command, and a run's short
verdict (every metric behind --verbose)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from helpers.records import from_json, ran
from helpers.testloop import LoopMetrics

from common.runtime.metrics_record import RunMetrics
from services.cli import build_parser, main
from services.cli.summary import print_summary, verdict_rows
from services.mission.records import FleetMetrics

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


# -- the short verdict of run and launch -------------------------------------------------------
RUN = {
    "outcome": "success",
    "success": True,
    "end_reason": "goal",
    "reached_goal": True,
    "min_clearance_m": 1.2,
    "min_clearance_t_s": 59.9,
    "rho0_m": 1.0,
    "travel_time_s": 68.8,
    "path_length_m": 92.4,
    "mean_speed_mps": 1.343,
    "xte_planned_rms_m": 0.154,
    "xte_planned_max_m": 0.46,
    "tracking_rms_m": 0.9,  # the moving obstacles' tracks: not the vehicle's cross-track
    "estimation_rms_m": 0.157,
    "estimation_max_m": 0.629,
    "commands_applied": 681,
    "link_stats": {"a": {"sent": 1}},
}


def _printed(capsys: pytest.CaptureFixture[str], metrics: RunMetrics[Any], **kw: bool) -> str:
    print_summary(metrics, [("metrics", Path("d/metrics.json")), ("plot", Path("d/run.png"))], **kw)
    return capsys.readouterr().out


def test_a_run_ends_with_a_short_verdict_and_where_its_outputs_are(
    capsys: pytest.CaptureFixture[str],
) -> None:
    assert _printed(capsys, from_json(RUN), all_metrics=False).splitlines() == [
        "  outcome          success",
        "  min clearance    1.20 m at t = 59.90 s (rho0 = 1.0 m)",
        "  travel time      68.80 s (92.4 m at 1.34 m/s)",
        "  cross-track RMS  0.154 m to the path in force (max 0.46 m)",
        "  estimation RMS   0.157 m of the position estimate (max 0.629 m)",
        "metrics: d/metrics.json (every metric: --verbose)",
        "plot: d/run.png",
    ]


def test_verbose_prints_every_scalar_metric_before_the_verdict(
    capsys: pytest.CaptureFixture[str],
) -> None:
    lines = _printed(capsys, from_json(RUN), all_metrics=True).splitlines()
    assert lines[0].split() == ["commands_applied", "681"]  # sorted by name
    assert sum(line.split()[0] == "outcome" for line in lines) == 2  # the table's, the verdict's
    assert lines[-2:] == ["metrics: d/metrics.json", "plot: d/run.png"]
    assert not any("link_stats" in line for line in lines)


def test_a_run_cut_short_says_how_far_from_the_goal_it_ended(
    capsys: pytest.CaptureFixture[str],
) -> None:
    short = {
        **RUN,
        "outcome": "not_reached",
        "success": False,
        "end_reason": "max_time",
        "reached_goal": False,
        "t_end_s": 5.0,
        "final_distance_to_goal_m": 89.41,
        "min_clearance_m": float("nan"),  # an empty world
        "estimation_rms_m": None,  # not measured
    }
    rows = dict(verdict_rows(from_json(short)))
    assert rows["outcome"] == "not_reached (the run ended on max_time)"
    assert rows["travel time"] == "goal not reached (t = 5.00 s, 89.4 m short)"
    assert rows["min clearance"] == "none measured (no obstacle in this world)"
    assert rows["estimation RMS"] == "not measured"


def test_a_fleets_verdict_gives_the_worst_vehicles_errors() -> None:
    fleet = {
        "outcome": "success",
        "reached_goal": True,
        "fleet_size": 2,
        "travel_time_s": 80.0,
        "min_clearance_m": 1.5,
        "min_separation_m": 9.17,
        "min_separation_pair": "auv1-auv2",
        "vehicles": {
            "auv1": {"xte_planned_rms_m": 0.1, "xte_planned_max_m": 0.3},
            "auv2": {"xte_planned_rms_m": 0.2, "xte_planned_max_m": 0.4},
        },
    }
    rows = dict(verdict_rows(from_json(fleet, FleetMetrics)))
    assert rows["cross-track RMS"] == "0.2 m to the path in force (max 0.4 m; auv2, the worst of 2)"
    assert rows["min clearance"] == "1.50 m; hull to hull 9.17 m (auv1 and auv2)"
    assert rows["travel time"] == "80.00 s (the last vehicle's arrival)"
    assert "estimation RMS" not in rows


def test_a_mission_without_the_verdicts_keys_prints_its_table(
    capsys: pytest.CaptureFixture[str],
) -> None:
    loop = LoopMetrics(final_x=1.5, final_error=None, trajectory_sha256="")
    out = _printed(capsys, ran(loop, ticks=20), all_metrics=False).splitlines()
    # the loop's own keys among the run's facts, every scalar sorted by name (no verdict)
    table = [line.split() for line in out[:-2]]
    assert ["final_x", "1.5"] in table and ["ticks", "20"] in table
    assert [row[0] for row in table] == sorted(row[0] for row in table)
    assert out[-2] == "metrics: d/metrics.json"


def test_run_and_launch_take_verbose_after_the_command() -> None:
    p = build_parser()
    a = p.parse_args(["run", "s.toml", "--verbose"])
    assert a.all_metrics and not a.verbose  # the top-level -v is debug logging
    a = p.parse_args(["-v", "launch", "s.toml"])
    assert a.verbose and not a.all_metrics
