"""REPORT.md of `tidelink reproduce`: terms, gains, verdicts, results per case, figures.

Each section is a small builder over ReportInputs; write_report composes them (the fixed
wording is in wording.py, the Markdown blocks in the sweep engine's markdown.py)."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from services.experiments.reproduction import wording
from services.experiments.reproduction.cases import Case
from services.experiments.reproduction.claims import (
    Cells,
    claims,
    estimate,
    fmt,
    paper_table,
    time_ratios,
    verdict_summary,
    verdict_table,
)
from services.experiments.reproduction.tuning import TUNED_GAINS, Tuning
from services.experiments.sweep.labels import CONTROLLER_NAMES
from services.experiments.sweep.markdown import Block, document, section, table
from services.experiments.sweep.summary import CellStats, success_text
from services.mission.outcome import OUTCOMES

# the columns of a results table, after controller, success and outcomes
TABLE = (
    ("travel_time_s", "travel time (s), eq. 21"),
    ("mean_speed_mps", "mean speed (m/s)"),
    ("xte_optimal_rms_m", "XTE to optimal path, RMS (m)"),
    ("xte_optimal_max_m", "XTE to optimal path, max (m)"),
    ("path_reentries", "returns to the path"),
    ("on_path_fraction", "share of actions on path"),
    ("control_actions", "control actions"),
    ("min_clearance_m", "min clearance (m)"),
    ("time_below_rho0_s", "time inside rho0 (s)"),
    ("max_executed_curvature_after_start", "max executed curvature (1/m)"),
    ("time_above_curvature_limit_s", "time above 1/R_min (s)"),
    ("replans", "replans"),
)
EQUAL_TERMS = ("perfect", "perfect-uncompensated", "lossy", "lossy-uncompensated")
GAINS_HEAD = (
    "controller",
    "gains searched",
    "rounds",
    "final grid (factors a; b)",
    "candidates run",
    "chosen",
    "interior?",
    "success",
    "XTE to path in force, RMS (m)",
)
CROSSING_TITLE = (
    "`crossing`: moving obstacles across the planned path (compensation on, replanning on)"
)


@dataclass(frozen=True, kw_only=True)
class ReportInputs:
    """Everything REPORT.md states."""

    scenario: str
    area: str  # e.g. "100 m x 40 m"
    runtime: str
    seeds: list[int]
    on_path_tol_m: float
    r_min_m: float
    rho0_m: float
    cells: list[CellStats]  # grid (case, controller)
    cases: tuple[Case, ...]  # the comparison's cases, in report order
    networks: dict[str, str]  # network label -> description
    figures: dict[str, list[str]]  # case -> figure files (relative to the report)
    errors: int
    crossing: str = ""  # the crossing scenario, "" when not run
    tuning: Tuning | None = None
    tune_step: float = 2.0
    tune_limit: int = 6
    tune_seeds: list[int] = field(default_factory=list)
    same_first_plan: dict[str, bool] = field(default_factory=dict)
    replan: bool = False  # whether the planner could replan (else the first plan is kept)
    corridor_m: float = 0.0  # the planner's corridor half-width around its path
    left_corridor: dict[tuple[str, str], tuple[int, int]] = field(default_factory=dict)
    command: str = ""


def _by_cell(inp: ReportInputs) -> Cells:
    return {(c.labels.get("case", ""), c.labels.get("controller", "")): c for c in inp.cells}


def _outcome_text(c: CellStats | None) -> str:
    if c is None or not c.n_judged:
        return "–"
    return " / ".join(str(c.outcomes.get(o, 0)) for o in OUTCOMES)


def _results_table(cells: Cells, case: str) -> list[str]:
    """Per controller: success, the runs by outcome and the mean [95 %] of every TABLE metric."""
    head = ["controller", "success", "success / rho0 breach / collision / not reached"]
    rows = [
        [
            name,
            success_text(c.success) if (c := cells.get((case, ctrl))) else "–",
            _outcome_text(c),
            *(fmt(estimate(cells, case, ctrl, m)) for m, _ in TABLE),
        ]
        for ctrl, name in CONTROLLER_NAMES.items()
    ]
    return table([*head, *(t for _, t in TABLE)], rows)


def _factor(i: int, step: float) -> str:
    return f"{step**i:g}"


def _span(lo: int, hi: int, step: float) -> str:
    """The factors step**lo .. step**hi, e.g. '0.5..2'."""
    return f"{_factor(lo, step)}..{_factor(hi, step)}"


def _gains(inp: ReportInputs, t: Tuning) -> list[str]:
    """The search's result per controller: its final grid, its choice, how that choice did."""
    step, rows = inp.tune_step, []
    for ctrl, best in t.best.items():
        box = t.boxes[ctrl]
        gains = ", ".join(f"`{k.rsplit('.', 1)[-1]}` = {v:.4g}" for k, v in best.gains.items())
        edges = box.edges(best)
        rows.append(
            [
                CONTROLLER_NAMES[ctrl],
                ", ".join(k.rsplit(".", 1)[-1] for k in TUNED_GAINS[ctrl]),
                str(t.rounds[ctrl]),
                f"{_span(box.a_lo, box.a_hi, step)}; {_span(box.b_lo, box.b_hi, step)}",
                str(sum(1 for c in t.candidates if c.controller == ctrl and c.runs)),
                f"{best.label}: {gains}",
                "yes" if not edges else f"no: {', '.join(edges)} at the search limit",
                f"{100 * best.success_rate:.0f} %",
                f"{best.xte_rms_m:.3f}",
            ]
        )
    return table(GAINS_HEAD, rows)


def _gains_section(inp: ReportInputs) -> list[str]:
    if inp.tuning is None:
        return section("Gains", wording.NO_SEARCH)
    step = inp.tune_step
    search = wording.SEARCH.substitute(
        step=f"{step:g}",
        seeds=inp.tune_seeds,
        first=_span(-1, 1, step),
        limit=_span(-inp.tune_limit, inp.tune_limit, step),
    )
    return section("Gains", search, _gains(inp, inp.tuning))


def _terms_section(inp: ReportInputs) -> list[str]:
    """What is compared, plainly, the rules every controller shares, and how to read it."""
    terms = [t.substitute(r_min=f"{inp.r_min_m:g}", rho0=f"{inp.rho0_m:g}") for t in wording.TERMS]
    return section(
        "What is compared, and on which terms",
        terms,
        wording.READING.substitute(on_path_tol=inp.on_path_tol_m),
        wording.REPLANNING if inp.replan else wording.ONE_PLAN,
    )


def _corridor_note(inp: ReportInputs, case: str) -> str:
    """How many runs went round an obstacle on the other side of the optimal path."""
    counts = [(name, inp.left_corridor.get((case, c))) for c, name in CONTROLLER_NAMES.items()]
    known = [(name, kn) for name, kn in counts if kn is not None]
    if not known:
        return ""
    text = ", ".join(f"{name} {k}/{n}" for name, (k, n) in known)
    left = any(k for _, (k, _) in known)
    what = f"{text}. {wording.CORRIDOR_LEFT}" if left else f"none ({text})."
    return wording.CORRIDOR.substitute(corridor=f"{inp.corridor_m:g}", what=what)


def _case_section(inp: ReportInputs, cells: Cells, case: Case) -> list[str]:
    """One case's results table, whether the first plans agreed, who left the corridor."""
    comp = "compensation on for all" if case.compensation else "compensation off for all"
    pre = "" if case.prefilter else ", eqs. (2)-(3) off"
    same = inp.same_first_plan.get(case.label)
    same_text = "unknown" if same is None else ("yes" if same else "no")
    return section(
        f"`{case.label}`: {case.network} network, {comp}{pre}",
        _results_table(cells, case.label),
        f"Same first (optimal) plan for the three controllers in every seed: {same_text}.",
        _corridor_note(inp, case.label),
        level=3,
    )


def _results_section(inp: ReportInputs, cells: Cells) -> list[str]:
    crossing: Block = []
    if inp.crossing:
        crossing = section(CROSSING_TITLE, _results_table(cells, "crossing"), level=3)
    return section("Results", *(_case_section(inp, cells, case) for case in inp.cases), crossing)


def _worst(cells: Cells, ctrl: str, metric: str) -> float:
    """The highest mean of a metric over the equal-terms cases (nan without data)."""
    means = (e.mean for c in EQUAL_TERMS if (e := estimate(cells, c, ctrl, metric)))
    return max(means, default=float("nan"))


def _constraints(inp: ReportInputs, cells: Cells) -> list[str]:
    """Facts about R_min and rho0 in execution, per controller over the equal-terms cases."""
    lines = []
    for ctrl, name in CONTROLLER_NAMES.items():
        judged = [cell for c in EQUAL_TERMS if (cell := cells.get((c, ctrl))) is not None]
        curvature = _worst(cells, ctrl, "max_executed_curvature_after_start")
        lines.append(
            wording.CONSTRAINT.substitute(
                name=name,
                breaches=sum(cell.outcomes.get("rho0_breach", 0) for cell in judged),
                contacts=sum(cell.outcomes.get("collision", 0) for cell in judged),
                runs=sum(cell.n_judged for cell in judged),
                curvature=f"{curvature:.3g}",
                limit=f"{1 / inp.r_min_m:.3g}",
                above=f"{_worst(cells, ctrl, 'time_above_curvature_limit_s'):.3g}",
            )
        )
    return lines


def _verdicts_section(inp: ReportInputs, cells: Cells) -> list[str]:
    """Which claims hold in which equal-terms case, in plain words, and the hard limits."""
    judged = [c for c in EQUAL_TERMS if any(k[0] == c for k in cells)]
    return section(
        "Which of the paper's claims hold on equal terms",
        wording.VERDICTS,
        verdict_table(cells, judged),
        "In plain words:",
        verdict_summary(cells, judged),
        "Hard constraints in execution (all equal-terms cases):",
        _constraints(inp, cells),
    )


def _opening(inp: ReportInputs) -> list[str]:
    """The title, what ran where, how to regenerate it, and how many runs failed."""
    nets = "; ".join(f"**{k}**: {v}" for k, v in inp.networks.items())
    crossing = f", and `{inp.crossing}` (moving obstacles across the path)" if inp.crossing else ""
    scene = wording.SCENE.substitute(
        scenario=inp.scenario,
        area=inp.area,
        crossing=crossing,
        seeds=inp.seeds,
        runtime=inp.runtime,
        networks=nets,
    )
    return section(
        wording.TITLE,
        scene,
        f"Regenerate with `{inp.command}`." if inp.command else "",
        f"**{inp.errors} runs failed to execute** (see the sweeps' summary.md)."
        if inp.errors
        else "",
        level=1,
    )


def _figures_section(inp: ReportInputs) -> list[str]:
    return section(
        "Figures",
        *(
            section(f"`{label}`, seed {inp.seeds[0]}", [f"![{f}]({f})" for f in figs], level=3)
            for label, figs in inp.figures.items()
        ),
    )


def write_report(path: Path, inp: ReportInputs) -> None:
    """REPORT.md: the terms, the gains, the verdicts, each case's results, the figures."""
    cells = _by_cell(inp)
    by_case = [line for c in inp.cases if c.label in EQUAL_TERMS for line in claims(cells, c.label)]
    beside = (
        "Ours in case `perfect` (the paper's simulation has no network in the loop):",
        paper_table(cells, "perfect"),
        f"Travel-time ratios: {time_ratios(cells, 'perfect')}.",
    )
    text = document(
        _opening(inp),
        _terms_section(inp),
        _gains_section(inp),
        _verdicts_section(inp, cells),
        _results_section(inp, cells),
        section("The paper's claims, case by case", by_case),
        section("Beside the paper", *beside),
        _figures_section(inp),
        section("What cannot be compared", wording.CANNOT_COMPARE),
    )
    path.write_text(text)
