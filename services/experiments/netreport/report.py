"""REPORT.md of `tidelink network-report`: the issue's goals, each controller's cliff, the
tables and figures of every sweep, and what the command sequences cost.

Each section is a small builder; write_report composes them (the fixed wording is in
wording.py, the judging in goals.py, the Markdown blocks in the sweep engine's markdown.py)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from services.experiments.netreport import wording
from services.experiments.netreport.goals import (
    GOALS,
    SweepCells,
    cliff,
    goal_met,
    pooled,
    rate,
    worst,
)
from services.experiments.netreport.sequence_cost import CostRow
from services.experiments.sweep.labels import CONTROLLER_NAMES
from services.experiments.sweep.markdown import document, section, table
from services.experiments.sweep.stats import Estimate
from services.experiments.sweep.summary import FAILURES, CellStats

GOALS_HEAD = (
    "goal (NURBS method)",
    "judged at",
    "sequences on (worst)",
    "met",
    "sequences off (worst)",
)
CLIFFS_HEAD = ("sweep", "controller", "sequences on", "sequences off", "all levels, on / off")
COST_HEAD = (
    "controller",
    "horizon (s)",
    "entries",
    "bytes",
    "×",
    "step p50 (ms)",
    "p95 (ms)",
    "×",
    "then preparing p50 (ms)",
)


def _m(c: CellStats | None, metric: str, digits: int = 2) -> str:
    e: Estimate | None = c.metrics.get(metric) if c else None
    return "–" if e is None or e.n == 0 else f"{e.mean:.{digits}f}"


def _goals(sweeps: list[SweepCells]) -> list[str]:
    """Each of the issue's goals: where it is judged, the worst level on and off, met or not."""
    by_name = {s.name: s for s in sweeps}
    rows = []
    for g in GOALS:
        sw = by_name.get(g.sweep)
        if sw is None:
            continue
        levels, met, contact = goal_met(g, sw)
        extra = f"; runs with contact: {contact}" if g.no_contact else ""
        rows.append(
            [
                g.text,
                ", ".join(v.label for v in levels),
                f"{worst(sw, levels, 'on')}{extra}",
                "yes" if met else "**no**",
                worst(sw, levels, "off"),
            ]
        )
    return table(GOALS_HEAD, rows)


def _cliffs(sweeps: list[SweepCells]) -> list[str]:
    """Every sweep's cliff per controller, on and off, and its success over all levels."""
    rows = [
        [
            sw.name,
            name,
            cliff(sw, ctrl, "on"),
            cliff(sw, ctrl, "off"),
            f"{pooled(sw, ctrl, 'on')} / {pooled(sw, ctrl, 'off')}",
        ]
        for sw in sweeps
        for ctrl, name in CONTROLLER_NAMES.items()
    ]
    return table(CLIFFS_HEAD, rows)


def _count(outcome: str) -> Callable[[CellStats], str]:
    """A cell's number of runs that ended in `outcome`, as text."""
    return lambda c: str(c.outcomes.get(outcome, 0))


def _pair(on: CellStats | None, off: CellStats | None, f: Callable[[CellStats], str]) -> str:
    return " / ".join("–" if c is None else f(c) for c in (on, off))


def _cell_rows(sw: SweepCells) -> list[list[str]]:
    """Per level and controller, on / off: success, failures by outcome, three means."""
    rows = []
    for v in sw.axis.values:
        for ctrl, name in CONTROLLER_NAMES.items():
            on, off = sw.cell(v.label, "on", ctrl), sw.cell(v.label, "off", ctrl)
            rows.append(
                [
                    v.label,
                    name,
                    _pair(on, off, rate),
                    *(_pair(on, off, _count(o)) for o in FAILURES),
                    _pair(on, off, lambda c: _m(c, "min_clearance_m")),
                    _pair(on, off, lambda c: _m(c, "xte_planned_rms_m")),
                    _pair(on, off, lambda c: _m(c, "blind_time_s", 1)),
                ]
            )
    return rows


def _sweep_section(sw: SweepCells) -> list[str]:
    """One sweep: what ran, each controller's cliff, its figures, every cell."""
    cliffs = [
        [name, cliff(sw, ctrl, "on"), cliff(sw, ctrl, "off")]
        for ctrl, name in CONTROLLER_NAMES.items()
    ]
    cells_head = [sw.axis.name, "controller", "success", "inside rho0", "contact"]
    cells_head += ["not reached", "min clearance", "XTE", "HOLD/FAILSAFE"]
    return section(
        sw.name.capitalize(),
        wording.SWEEP.substitute(
            file=sw.file,
            x_label=sw.axis.x_label,
            runs=sw.runs,
            errors=sw.errors,
            first=sw.first_seed,
            last=sw.first_seed + sw.seeds - 1,
        ),
        table(["controller", "sequences on", "sequences off"], cliffs),
        [f"![{f}]({f})" for f in sw.figures],
        wording.PER_CELL,
        table(cells_head, _cell_rows(sw)),
    )


def _cost_section(cost: list[CostRow]) -> list[str]:
    rows = [
        [
            CONTROLLER_NAMES[r.controller],
            f"{r.horizon_s:g}",
            str(r.entries),
            f"{r.bytes:.0f}",
            f"{r.bytes_ratio:.1f}",
            f"{r.step_p50_ms:.2f}",
            f"{r.step_p95_ms:.2f}",
            f"{r.time_ratio:.0f}",
            f"{r.prepare_p50_ms:.2f}",
        ]
        for r in cost
    ]
    return section("What the sequences cost", wording.COST, table(COST_HEAD, rows))


def write_report(
    path: Path,
    sweeps: list[SweepCells],
    cost: list[CostRow],
    *,
    runtime: str,
    command: str,
    world: str = "configs/default.toml (calm water)",
) -> None:
    """REPORT.md: how to regenerate it, what is compared, the goals, the cliffs, each sweep."""
    regenerate = wording.REGENERATE.substitute(
        command=command or "tidelink network-report",
        runs=sum(s.runs for s in sweeps),
        runtime=runtime,
        errors=sum(s.errors for s in sweeps),
    )
    text = document(
        section(wording.TITLE, regenerate, f"World: {world}.", wording.INTRO, level=1),
        section("The issue's goals", _goals(sweeps)),
        section("Where each controller's cliff is", wording.CLIFFS, _cliffs(sweeps)),
        *(_sweep_section(sw) for sw in sweeps),
        _cost_section(cost),
    )
    path.write_text(text)
