"""The issue's goals for the network report, and where each controller's cliff is, judged on
a sweep's cells (grid: fault axis, mechanism, controller)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from services.experiments.sweep.schema import Axis, AxisValue
from services.experiments.sweep.summary import CellStats

GOAL = 0.95  # the success target


@dataclass(frozen=True, kw_only=True)
class SweepCells:
    """One sweep's aggregated cells (grid: fault axis, mechanism, controller) and figures."""

    name: str
    file: str
    axis: Axis
    seeds: int
    first_seed: int
    cells: list[CellStats]
    runs: int
    errors: int
    figures: list[str] = field(default_factory=list)  # relative to the report

    def cell(self, level: str, mech: str, ctrl: str) -> CellStats | None:
        for c in self.cells:
            lab = c.labels
            if (lab.get(self.axis.name), lab.get("mechanism"), lab.get("controller")) == (
                level,
                mech,
                ctrl,
            ):
                return c
        return None


@dataclass(frozen=True, kw_only=True)
class Goal:
    """One of the issue's targets for the NURBS method with sequences on."""

    sweep: str
    text: str
    levels: Callable[[float], bool]  # the fault levels (axis x) it is judged at
    no_contact: bool = False


GOALS = (
    Goal(sweep="delay", text="≥ 95 % up to 1.0 s one-way delay", levels=lambda x: x <= 1.0),
    Goal(sweep="loss", text="≥ 95 % at 50 % Bernoulli loss", levels=lambda x: x == 0.5),
    Goal(sweep="burst", text="≥ 95 % at mean loss bursts of 20", levels=lambda x: x == 20),
    Goal(
        sweep="outage",
        text="≥ 95 % through a 10 s outage, without contact",
        levels=lambda x: x == 10,
        no_contact=True,
    ),
)


def rate(c: CellStats | None) -> str:
    """A cell's successes of its judged runs, "k/n (p %)"."""
    if c is None or not c.n_judged:
        return "–"
    k = c.outcomes.get("success", 0)
    return f"{k}/{c.n_judged} ({100 * k / c.n_judged:.0f} %)"


def _ok(c: CellStats | None) -> bool:
    return c is not None and c.success.n > 0 and c.success.mean >= GOAL


def cliff(sw: SweepCells, ctrl: str, mech: str) -> str:
    """Where success first falls below 95 % along the fault axis, and the last level before."""
    last: AxisValue | None = None
    for v in sw.axis.values:
        c = sw.cell(v.label, mech, ctrl)
        if c is None or not c.n_judged:
            continue
        if not _ok(c):
            held = f"holds to {last.label}, " if last else ""
            return f"{held}falls at {v.label}: {rate(c)}"
        last = v
    return f"≥ 95 % throughout (to {last.label})" if last else "–"


def pooled(sw: SweepCells, ctrl: str, mech: str) -> str:
    """Success over every level of a sweep, as a percentage of the runs judged."""
    cs = [c for v in sw.axis.values if (c := sw.cell(v.label, mech, ctrl)) is not None]
    n = sum(c.n_judged for c in cs)
    return f"{100 * sum(c.outcomes.get('success', 0) for c in cs) / n:.0f} %" if n else "–"


def worst(sw: SweepCells, levels: list[AxisValue], mech: str) -> str:
    """The NURBS method's lowest success over the levels, and where."""
    judged = [
        (c.success.mean, v)
        for v in levels
        if (c := sw.cell(v.label, mech, "nurbs")) is not None and c.n_judged
    ]
    if not judged:
        return "–"
    _, v = min(judged, key=lambda p: p[0])
    return f"{rate(sw.cell(v.label, mech, 'nurbs'))} at {v.label}"


def goal_met(g: Goal, sw: SweepCells) -> tuple[list[AxisValue], bool, int]:
    """The levels a goal is judged at, whether the NURBS method with sequences on meets it
    there, and its runs with contact."""
    levels = [v for v in sw.axis.values if g.levels(v.x)]
    on = [sw.cell(v.label, "on", "nurbs") for v in levels]
    contact = sum(c.outcomes.get("collision", 0) for c in on if c)
    met = bool(on) and all(_ok(c) for c in on) and (not g.no_contact or contact == 0)
    return levels, met, contact
