"""REPORT.md of `tidelink network-report`: the issue's goals, each controller's cliff, the
tables and figures of every sweep, and what the command sequences cost."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

from services.experiments.netreport.sequence_cost import CostRow
from services.experiments.sweep.labels import CONTROLLER_NAMES
from services.experiments.sweep.schema import Axis, AxisValue
from services.experiments.sweep.stats import Estimate
from services.experiments.sweep.summary import FAILURES, CellStats

GOAL = 0.95  # the issue's success target
CONTROLLERS = ("nurbs", "backstepping", "fuzzy_pid")
MECHANISMS = ("on", "off")


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


def _rate(c: CellStats | None) -> str:
    if c is None or not c.n_judged:
        return "–"
    k = c.outcomes.get("success", 0)
    return f"{k}/{c.n_judged} ({100 * k / c.n_judged:.0f} %)"


def _ok(c: CellStats | None) -> bool:
    return c is not None and c.success.n > 0 and c.success.mean >= GOAL


def _m(c: CellStats | None, metric: str, digits: int = 2) -> str:
    e: Estimate | None = c.metrics.get(metric) if c else None
    return "–" if e is None or e.n == 0 else f"{e.mean:.{digits}f}"


def cliff(sw: SweepCells, ctrl: str, mech: str) -> str:
    """Where success first falls below 95 % along the fault axis, and the last level before."""
    last: AxisValue | None = None
    for v in sw.axis.values:
        c = sw.cell(v.label, mech, ctrl)
        if c is None or not c.n_judged:
            continue
        if not _ok(c):
            held = f"holds to {last.label}, " if last else ""
            return f"{held}falls at {v.label}: {_rate(c)}"
        last = v
    return f"≥ 95 % throughout (to {last.label})" if last else "–"


def pooled(sw: SweepCells, ctrl: str, mech: str) -> str:
    """Success over every level of a sweep, as a percentage of the runs judged."""
    cs = [c for v in sw.axis.values if (c := sw.cell(v.label, mech, ctrl)) is not None]
    n = sum(c.n_judged for c in cs)
    return f"{100 * sum(c.outcomes.get('success', 0) for c in cs) / n:.0f} %" if n else "–"


def _worst(sw: SweepCells, levels: list[AxisValue], mech: str) -> str:
    """The NURBS method's lowest success over the levels, and where."""
    judged = [
        (c.success.mean, v)
        for v in levels
        if (c := sw.cell(v.label, mech, "nurbs")) is not None and c.n_judged
    ]
    if not judged:
        return "–"
    _, v = min(judged, key=lambda p: p[0])
    return f"{_rate(sw.cell(v.label, mech, 'nurbs'))} at {v.label}"


def _goal_rows(sweeps: dict[str, SweepCells]) -> list[str]:
    lines = [
        "| goal (NURBS method) | judged at | sequences on (worst) | met | sequences off (worst) |",
        "|---|---|---|---|---|",
    ]
    for g in GOALS:
        sw = sweeps.get(g.sweep)
        if sw is None:
            continue
        levels = [v for v in sw.axis.values if g.levels(v.x)]
        on = [sw.cell(v.label, "on", "nurbs") for v in levels]
        contact = sum(c.outcomes.get("collision", 0) for c in on if c)
        met = bool(on) and all(_ok(c) for c in on) and (not g.no_contact or contact == 0)
        extra = f"; runs with contact: {contact}" if g.no_contact else ""
        lines.append(
            f"| {g.text} | {', '.join(v.label for v in levels)} | "
            f"{_worst(sw, levels, 'on')}{extra} | {'yes' if met else '**no**'} | "
            f"{_worst(sw, levels, 'off')} |"
        )
    return lines


def _count(outcome: str) -> Callable[[CellStats], str]:
    """A cell's number of runs that ended in `outcome`, as text."""
    return lambda c: str(c.outcomes.get(outcome, 0))


def _pair(on: CellStats | None, off: CellStats | None, f: Callable[[CellStats], str]) -> str:
    return " / ".join("–" if c is None else f(c) for c in (on, off))


def _sweep_section(sw: SweepCells) -> list[str]:
    lines = [
        f"## {sw.name.capitalize()}",
        "",
        f"`{sw.file}`: {sw.axis.x_label}; {sw.runs} runs ({sw.errors} failed to run), "
        f"seeds {sw.first_seed}–{sw.first_seed + sw.seeds - 1} per cell.",
        "",
        "| controller | sequences on | sequences off |",
        "|---|---|---|",
    ]
    for ctrl in CONTROLLERS:
        lines.append(
            f"| {CONTROLLER_NAMES[ctrl]} | {cliff(sw, ctrl, 'on')} | {cliff(sw, ctrl, 'off')} |"
        )
    lines += ["", *(f"![{f}]({f})" for f in sw.figures), ""]
    lines += [
        "Per cell, sequences on / off: success (goal, no contact, never inside rho0); the "
        "failed runs by outcome (goal reached but inside rho0 / contact / goal not reached); "
        "mean minimum clearance (m); mean cross-track error to the path in force (RMS, m); "
        "mean time in HOLD or FAILSAFE (s).",
        "",
        f"| {sw.axis.name} | controller | success | inside rho0 | contact | not reached | "
        "min clearance | XTE | HOLD/FAILSAFE |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for v in sw.axis.values:
        for ctrl in CONTROLLERS:
            on, off = sw.cell(v.label, "on", ctrl), sw.cell(v.label, "off", ctrl)
            lines.append(
                f"| {v.label} | {CONTROLLER_NAMES[ctrl]} | {_pair(on, off, _rate)} | "
                + " | ".join(_pair(on, off, _count(o)) for o in FAILURES)
                + f" | {_pair(on, off, lambda c: _m(c, 'min_clearance_m'))} | "
                f"{_pair(on, off, lambda c: _m(c, 'xte_planned_rms_m'))} | "
                f"{_pair(on, off, lambda c: _m(c, 'blind_time_s', 1))} |"
            )
    return [*lines, ""]


def _cost_section(cost: list[CostRow]) -> list[str]:
    lines = [
        "## What the sequences cost",
        "",
        "The planner's control step (prediction, the entries computed on the newest state, the "
        "message: what the command waits for) and, after it, its preparing the next step (the "
        "rest of the rollout over the horizon, `controller.sequence.fresh_s`), timed on this "
        "machine's CPU clock along the default mission's first plan, and the command's size "
        "on the wire (envelope included); ratios to single commands measured in the same run "
        "(`scripts/bench_sequence.py`, `services/experiments/netreport/sequence_cost.py`). The "
        "control period is 100 ms.",
        "",
        "| controller | horizon (s) | entries | bytes | × | step p50 (ms) | p95 (ms) | × "
        "| then preparing p50 (ms) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in cost:
        lines.append(
            f"| {CONTROLLER_NAMES[r.controller]} | {r.horizon_s:g} | {r.entries} | {r.bytes:.0f} | "
            f"{r.bytes_ratio:.1f} | {r.step_p50_ms:.2f} | {r.step_p95_ms:.2f} | "
            f"{r.time_ratio:.0f} | {r.prepare_p50_ms:.2f} |"
        )
    return [*lines, ""]


INTRO = """\
What is compared, on the default mission's field in the world above (the calm
`configs/default.toml` is the paper's), inproc, every controller on equal terms:

- **sequences on** (`controller.sequence.horizon_s = 10`, the default): packet-based
  predictive control. Each command carries the controller's commands for now and every
  0.1 s of the next 10 s, each computed on the state predicted for its time: from the
  estimate's newest fix, forward under the commands already sent (those in flight
  included) with a model of the vehicle's response (eq. (7), speed and yaw lags, R_min).
  The vehicle applies the entry for its own time from the newest command it holds, keeps
  consuming the buffer through a loss or an outage, and the last entries bring it to rest
  on its path (the stop tail) instead of running on blind into HOLD;
- **sequences off** (`horizon_s = 0`, the ablation): single commands computed as before
  sequences existed (the controller predicts the estimate forward at constant twist over
  its age plus the downlink delay).

Both measure the delay instead of assuming it (the downlink from the vehicle's status:
its median; staleness is the estimate's age beyond the delay it arrives with), so
the 'off' columns are not the old code: before issue 16 a 1 s delay made every estimate
stale and the vehicle never moved. Success = reached the goal without contact and never
inside the safety distance rho0; with 20 seeds, 95 % allows one failed run (the Wilson 95 %
interval of 19/20 is 76–99 %)."""


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
    by_name = {s.name: s for s in sweeps}
    runs, errors = sum(s.runs for s in sweeps), sum(s.errors for s in sweeps)
    lines = [
        "# Control that survives the network: command sequences, measured delay, prediction",
        "",
        f"Regenerate with `{command or 'tidelink network-report'}` ({runs} runs, {runtime}, "
        f"{errors} failed to run; the runs resume from the output folder).",
        "",
        f"World: {world}.",
        "",
        INTRO,
        "",
        "## The issue's goals",
        "",
        *_goal_rows(by_name),
        "",
        "## Where each controller's cliff is",
        "",
        "The last fault level up to which a controller succeeds in ≥ 95 % of the runs, and "
        "the first where it does not; and its success over every level of the sweep.",
        "",
        "| sweep | controller | sequences on | sequences off | all levels, on / off |",
        "|---|---|---|---|---|",
    ]
    for sw in sweeps:
        for ctrl in CONTROLLERS:
            lines.append(
                f"| {sw.name} | {CONTROLLER_NAMES[ctrl]} | {cliff(sw, ctrl, 'on')} | "
                f"{cliff(sw, ctrl, 'off')} | {pooled(sw, ctrl, 'on')} / "
                f"{pooled(sw, ctrl, 'off')} |"
            )
    lines.append("")
    for sw in sweeps:
        lines += _sweep_section(sw)
    lines += _cost_section(cost)
    path.write_text("\n".join(lines) + "\n")
