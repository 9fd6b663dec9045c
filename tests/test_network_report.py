"""`tidelink network-report` end to end on the small scenario, and its cliff finding."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.cli.sweep_commands import _regenerate_command
from services.experiments.netreport.goals import SweepCells, cliff
from services.experiments.netreport.networked import NetworkOptions, in_world, network_report
from services.experiments.netreport.report import write_report
from services.experiments.sweep.schema import Axis, AxisValue, load_experiment
from services.experiments.sweep.stats import wilson
from services.experiments.sweep.summary import CellStats

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"

DELAY = f"""
name = "networked-delay"
scenario = "{SMALL}"
seeds = 1
controllers = ["nurbs"]
x_axis = "delay"
# the runs that reach the goal do so by ~30 s; the one that does not (1 s delay without
# sequences) replans on until max_time, which cost ~40 s of the test at 60 s
set = {{ "run.max_time_s" = 40.0 }}

[[axes]]
name = "delay"
x_label = "one-way delay (s)"
[[axes.values]]
label = "0ms"
x = 0.0
set = {{ "network.default" = {{}} }}
[[axes.values]]
label = "1000ms"
x = 1.0
set = {{ "network.default" = {{ delay_s = 1.0, jitter = "normal", jitter_s = 0.2 }} }}

[[axes]]
name = "mechanism"
[[axes.values]]
label = "on"
set = {{ "controller.sequence.horizon_s" = 10.0 }}
[[axes.values]]
label = "off"
set = {{ "controller.sequence.horizon_s" = 0.0 }}
"""


@pytest.mark.background
def test_the_report_runs_the_sweeps_and_writes_goals_cliffs_figures_and_cost(
    tmp_path: Path,
) -> None:
    experiments = tmp_path / "experiments"
    experiments.mkdir()
    (experiments / "delay.toml").write_text(DELAY)
    report_dir = tmp_path / "report"
    opts = NetworkOptions(
        out=tmp_path / "runs",
        report_dir=report_dir,
        experiments=experiments,
        sweeps=("delay",),
        cost_steps=3,
        cost_horizons=(0.0, 10.0),  # each (controller, horizon) plans the default mission once
        command="tidelink network-report (test)",
    )
    res = network_report(opts)
    assert (res.runs, res.errors) == (4, 0)  # 2 delays x on/off x 1 controller x 1 seed
    text = res.report.read_text()
    assert "Regenerate with `tidelink network-report (test)`" in text
    assert "| ≥ 95 % up to 1.0 s one-way delay | 0ms, 1000ms |" in text
    assert "## Where each controller's cliff is" in text and "## Delay" in text
    assert "## What the sequences cost" in text and "| NURBS method | 10 | 100 |" in text
    for metric in ("success", "xte_planned_rms_m", "min_clearance_m", "blind_time_s"):
        figure = f"figures/delay/{metric}.png"
        assert (report_dir / figure).read_bytes()[:4] == b"\x89PNG"
        assert f"![{figure}]({figure})" in text
    # resumable: a second call runs nothing again
    assert network_report(opts).runs == 4
    assert len((tmp_path / "runs" / "delay" / "results.csv").read_text().splitlines()) == 5


def _sweep(rates: list[int]) -> SweepCells:
    axis = Axis(name="loss", values=tuple(AxisValue(label=f"L{i}", x=i) for i in range(4)))
    cells = [
        CellStats(
            labels={"loss": f"L{i}", "mechanism": "on", "controller": "nurbs"},
            n_runs=20,
            n_errors=0,
            success=wilson(k, 20),
            metrics={},
            outcomes={"success": k, "collision": 20 - k},
        )
        for i, k in enumerate(rates)
    ]
    return SweepCells(
        name="loss", file="x", axis=axis, seeds=20, first_seed=1, cells=cells, runs=80, errors=0
    )


@pytest.mark.parametrize(
    ("rates", "text"),
    [
        ([20, 20, 20, 19], "≥ 95 % throughout (to L3)"),
        ([20, 19, 18, 20], "holds to L1, falls at L2: 18/20 (90 %)"),  # the first fall counts
        ([17, 20, 20, 20], "falls at L0: 17/20 (85 %)"),
    ],
)
def test_the_cliff_is_the_first_level_below_95_percent(rates: list[int], text: str) -> None:
    assert cliff(_sweep(rates), "nurbs", "on") == text
    assert cliff(_sweep(rates), "nurbs", "off") == "–"  # no cells


@pytest.mark.parametrize(
    ("argv", "expected"),
    [
        (["reproduce", "--jobs", "2", "--out", "/tmp/r"], "tidelink reproduce --jobs 2"),
        (["network-report", "--out=/tmp/n", "--seeds", "5"], "tidelink network-report --seeds 5"),
        (
            ["reproduce", "--scenario", "my field.toml"],
            "tidelink reproduce --scenario 'my field.toml'",
        ),
    ],
)
def test_a_report_names_the_command_without_the_folder_its_runs_went_to(
    argv: list[str], expected: str
) -> None:
    assert _regenerate_command(argv) == expected


def test_a_report_in_another_world_runs_there_on_its_time_limit_and_names_it(
    tmp_path: Path,
) -> None:
    exp = load_experiment(Path("configs/experiments/networked/delay.toml"))
    ocean = in_world(exp, Path("configs/ocean.toml"))
    assert ocean.scenario == str(Path("configs/ocean.toml").resolve())
    assert "run.max_time_s" in exp.set and "run.max_time_s" not in ocean.set
    assert ocean.axes == exp.axes and ocean.seeds == exp.seeds
    report = tmp_path / "REPORT.md"
    write_report(report, [], [], runtime="inproc", command="c", world="configs/ocean.toml")
    assert "World: configs/ocean.toml." in report.read_text()
