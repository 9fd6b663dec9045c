"""The three Markdown reports (reproduce's REPORT.md, network-report's REPORT.md, a sweep's
summary.md), rendered from small fixed fixtures, byte for byte against golden files: a
refactoring of how a report is put together must not change a character of it."""

from __future__ import annotations

from pathlib import Path

import pytest

from services.experiments.netreport.goals import SweepCells
from services.experiments.netreport.report import write_report as write_network_report
from services.experiments.netreport.sequence_cost import CostRow
from services.experiments.reproduction.cases import CASES
from services.experiments.reproduction.report import ReportInputs
from services.experiments.reproduction.report import write_report as write_reproduce_report
from services.experiments.reproduction.tuning import Box, Candidate, Tuning
from services.experiments.sweep.schema import Axis, AxisValue
from services.experiments.sweep.summary import aggregate, write_summary

GOLDEN = Path(__file__).resolve().parent / "golden" / "reports"
CONTROLLERS = ("nurbs", "backstepping", "fuzzy_pid")
OUTCOME_CYCLE = ("success", "success", "success", "rho0_breach", "collision", "not_reached")


def _row(labels: dict[str, str], i: int, seed: int) -> dict[str, str]:
    """A results.csv row whose numbers vary with the cell (i) and the seed."""
    outcome = OUTCOME_CYCLE[(i + seed) % len(OUTCOME_CYCLE)]
    reached = outcome in ("success", "rho0_breach")
    t = 60.0 + 3.0 * i + 0.7 * seed
    return {
        **labels,
        "run_id": f"r{i}-{seed}",
        "seed": str(seed),
        "status": "ok",
        "reached_goal": "1.0" if reached else "0.0",
        "success": "1.0" if outcome == "success" else "0.0",
        "outcome": outcome,
        "travel_time_s": repr(t),
        "mean_speed_mps": repr(90.0 / t),
        "path_length_m": repr(90.0 + 0.5 * i + 0.1 * seed),
        "xte_optimal_rms_m": repr(0.1 + 0.02 * i + 0.01 * seed),
        "xte_optimal_max_m": repr(0.4 + 0.05 * i + 0.03 * seed),
        "xte_planned_rms_m": repr(0.08 + 0.01 * i + 0.005 * seed),
        "path_reentries": str((i + seed) % 4),
        "on_path_fraction": repr(0.9 - 0.01 * i - 0.005 * seed),
        "control_actions": str(int(10 * t)),
        "control_actions_on_path": str(int(9 * t)),
        "min_clearance_m": repr(1.5 - 0.05 * i - 0.02 * seed),
        "time_below_rho0_s": repr(0.1 * ((i + seed) % 3)),
        "max_executed_curvature_after_start": repr(0.2 + 0.01 * i),
        "time_above_curvature_limit_s": repr(0.05 * (seed % 2)),
        "replans": str(seed % 3),
        "collisions": "1" if outcome == "collision" else "0",
        "hold_time_s": repr(0.5 * (seed % 2)),
        "failsafe_time_s": "0.0",
        "blind_time_s": repr(0.5 * (seed % 2) + 0.1 * i),
        "on_time": "True" if seed % 2 else "False",
    }


def _rows(grid: dict[str, tuple[str, ...]], seeds: int) -> list[dict[str, str]]:
    cells: list[dict[str, str]] = [{}]
    for name, labels in grid.items():
        cells = [{**c, name: lab} for c in cells for lab in labels]
    return [_row(c, i, s) for i, c in enumerate(cells) for s in range(1, seeds + 1)]


def _candidate(ctrl: str, point: tuple[int, int], success: float, xte: float) -> Candidate:
    a, b = point
    return Candidate(
        controller=ctrl,
        label=f"a{2.0**a:g}_b{2.0**b:g}",
        point=point,
        gains={f"controller.{ctrl}.gain_a": 1.5 * 2.0**a, f"controller.{ctrl}.gain_b": 2.0**b},
        runs=2,
        success_rate=success,
        xte_rms_m=xte,
        travel_time_s=70.0,
    )


def _tuning() -> Tuning:
    best = {
        "nurbs": _candidate("nurbs", (0, 1), 1.0, 0.12),
        "backstepping": _candidate("backstepping", (-2, 0), 0.5, 0.31),
        "fuzzy_pid": _candidate("fuzzy_pid", (1, -1), 1.0, 0.2),
    }
    return Tuning(
        best=best,
        candidates=[*best.values(), _candidate("nurbs", (1, 1), 0.5, 0.4)],
        boxes={
            "nurbs": Box(a_lo=-1, a_hi=1, b_lo=-1, b_hi=2),
            "backstepping": Box(a_lo=-2, a_hi=1, b_lo=-1, b_hi=1),
            "fuzzy_pid": Box(),
        },
        rounds={"nurbs": 2, "backstepping": 2, "fuzzy_pid": 1},
    )


def render_reproduce(path: Path, *, tuned: bool) -> None:
    """reproduce's REPORT.md from a fixture grid (case x controller, 5 seeds)."""
    cases = (*(c.label for c in CASES), "crossing")
    cells = aggregate(_rows({"case": cases, "controller": CONTROLLERS}, 5), ("case", "controller"))
    write_reproduce_report(
        path,
        ReportInputs(
            scenario="configs/default.toml",
            area="100 m x 40 m",
            runtime="inproc",
            seeds=[1, 2, 3, 4, 5],
            on_path_tol_m=0.5,
            r_min_m=2.0,
            rho0_m=1.0,
            cells=cells,
            cases=CASES,
            networks={"perfect": "no delay, no loss", "lossy": "50 ms ± 20 ms, 5 % loss"},
            figures={"perfect": ["figures/perfect/fig2.png", "figures/perfect/fig6.png"]},
            errors=2 if tuned else 0,
            crossing="configs/crossing.toml" if tuned else "",
            tuning=_tuning() if tuned else None,
            tune_seeds=[101, 102],
            same_first_plan={"perfect": True, "lossy": False},
            replan=not tuned,
            corridor_m=3.0,
            left_corridor={
                ("perfect", "nurbs"): (0, 5),
                ("perfect", "fuzzy_pid"): (0, 5),
                ("lossy", "backstepping"): (2, 5),
            },
            command="tidelink reproduce --seeds 5" if tuned else "",
        ),
    )


def _sweep(name: str, axis: Axis, seeds: int) -> SweepCells:
    grid = {axis.name: tuple(v.label for v in axis.values), "mechanism": ("on", "off")}
    rows = _rows({**grid, "controller": CONTROLLERS}, seeds)
    return SweepCells(
        name=name,
        file=f"configs/experiments/networked/{name}.toml",
        axis=axis,
        seeds=seeds,
        first_seed=1,
        cells=aggregate(rows, (axis.name, "mechanism", "controller")),
        runs=len(rows),
        errors=1,
        figures=[f"figures/{name}/success.png"],
    )


def render_network(path: Path) -> None:
    """network-report's REPORT.md from two fixture sweeps and a cost table."""
    delay = Axis(
        name="delay",
        x_label="one-way delay (s)",
        values=tuple(AxisValue(label=f"{x:g}s", x=x) for x in (0.0, 0.5, 1.0, 2.0)),
    )
    outage = Axis(
        name="outage",
        x_label="outage (s)",
        values=tuple(AxisValue(label=f"{x:g}s", x=x) for x in (0.0, 10.0)),
    )
    cost = [
        CostRow(
            controller=c,
            horizon_s=h,
            entries=int(h * 10) + 1,
            bytes=120.0 + 40 * h,
            bytes_ratio=1.0 + h,
            step_p50_ms=0.3 + 0.1 * h,
            step_p95_ms=0.5 + 0.2 * h,
            time_ratio=1.0 + 3 * h,
            prepare_p50_ms=0.05 * h,
        )
        for c in CONTROLLERS
        for h in (0.0, 10.0)
    ]
    write_network_report(
        path,
        [_sweep("delay", delay, 6), _sweep("outage", outage, 3)],
        cost,
        runtime="inproc",
        command="tidelink network-report --seeds 6",
    )


def render_summary(folder: Path) -> None:
    """A sweep's summary.md and summary.csv, with a failed run and cells of few seeds."""
    grid = ("controller", "delay")
    rows = _rows({"controller": CONTROLLERS, "delay": ("0s", "1s")}, 4)
    failed = {**rows[0], "status": "error", "run_id": "bad", "error": "boom | at t = 3 s"}
    rows = [failed, *rows[1:]]
    cells = aggregate(rows, grid)
    write_summary(folder, "Sweep golden", "An intro.", cells, grid, [failed])


def _check(made: Path, golden: str) -> None:
    want = (GOLDEN / golden).read_text()
    assert made.read_text() == want, f"{golden} changed: diff {made} {GOLDEN / golden}"


@pytest.mark.parametrize("tuned", [True, False])
def test_the_reproduce_report_is_unchanged(tmp_path: Path, tuned: bool) -> None:
    render_reproduce(tmp_path / "REPORT.md", tuned=tuned)
    _check(tmp_path / "REPORT.md", f"reproduce-{'tuned' if tuned else 'untuned'}.md")


def test_the_network_report_is_unchanged(tmp_path: Path) -> None:
    render_network(tmp_path / "REPORT.md")
    _check(tmp_path / "REPORT.md", "network.md")


def test_the_sweep_summary_is_unchanged(tmp_path: Path) -> None:
    render_summary(tmp_path)
    _check(tmp_path / "summary.md", "summary.md")
    _check(tmp_path / "summary.csv", "summary.csv")
