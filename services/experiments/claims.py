"""The paper's section-4 numbers and claims, and how our per-cell estimates bear them out."""

from __future__ import annotations

import math
from dataclasses import dataclass

from services.experiments.stats import Estimate
from services.experiments.summary import CellStats

NAMES = {"nurbs": "NURBS method", "backstepping": "Backstepping", "fuzzy_pid": "immune fuzzy PID"}
BASELINES = ("backstepping", "fuzzy_pid")


@dataclass(frozen=True, kw_only=True)
class PaperResult:
    """One controller's numbers in the paper."""

    controls: int
    on_path: int | None  # not stated for the NURBS method
    time_min: float


# She & Tian, sections 4.1 and 4.2 (MATLAB simulation, 100 x 40 area, no network in the loop)
PAPER = {
    "backstepping": PaperResult(controls=62, on_path=29, time_min=21.89),
    "fuzzy_pid": PaperResult(controls=85, on_path=4, time_min=32.5),
    "nurbs": PaperResult(controls=100, on_path=None, time_min=4.98),
}

Cells = dict[tuple[str, str], CellStats]  # (network, controller) -> statistics


def estimate(cells: Cells, net: str, ctrl: str, metric: str) -> Estimate | None:
    c = cells.get((net, ctrl))
    return c.metrics.get(metric) if c else None


def mean(cells: Cells, net: str, ctrl: str, metric: str) -> float:
    e = estimate(cells, net, ctrl, metric)
    return e.mean if e else math.nan


def fmt(e: Estimate | None) -> str:
    return e.text() if e else "–"


def compare(nurbs: Estimate | None, other: Estimate | None, nurbs_lower: bool) -> str:
    """Whether NURBS lies on the claimed side: 'yes' (95 % intervals apart), 'yes, CIs
    overlap', 'tie' (equal means), 'no' (the opposite side), or 'n/a' without data."""
    if nurbs is None or other is None:
        return "n/a"
    if not (math.isfinite(nurbs.mean) and math.isfinite(other.mean)):
        return "n/a"
    if nurbs.mean == other.mean:
        return "tie"
    on_side = nurbs.mean < other.mean if nurbs_lower else nurbs.mean > other.mean
    if not on_side:
        return "no"
    apart = nurbs.high < other.low if nurbs_lower else nurbs.low > other.high
    return "yes" if apart else "yes, CIs overlap"


def claim(cells: Cells, net: str, metric: str, nurbs_lower: bool, what: str) -> str:
    """One bullet: the claim, the verdict against both baselines, and the numbers."""
    verdicts = {
        b: compare(
            estimate(cells, net, "nurbs", metric), estimate(cells, net, b, metric), nurbs_lower
        )
        for b in BASELINES
    }
    if all(v == "yes" for v in verdicts.values()):
        head = "**matches**"
    elif all(v.startswith("yes") for v in verdicts.values()):
        head = "**matches in the means** (95 % intervals overlap)"
    elif any(v.startswith("yes") for v in verdicts.values()):
        head = "**partly matches**"
    else:
        head = "**does not match**"
    nums = ", ".join(
        f"{NAMES[k]} {fmt(estimate(cells, net, k, metric))}" for k in ("nurbs", *BASELINES)
    )
    detail = "; ".join(f"vs {NAMES[b]}: {v}" for b, v in verdicts.items())
    return f"- {what}: {head} on the {net} network. `{metric}`: {nums} ({detail})."


def claims(cells: Cells, net: str) -> list[str]:
    """Every qualitative claim of section 4 and the conclusions, judged on one network."""
    accuracy = "The NURBS method deviates least from the optimal path (accuracy, Figs. 2-5)"
    on_path = "The NURBS method has the largest share of control actions on the optimal path"
    fastest = "The NURBS method is fastest (time advantage, eq. 21, Fig. 6)"
    more = "The NURBS method issues more control actions than the baselines (conclusion (i))"
    out = [
        claim(cells, net, "xte_optimal_rms_m", True, accuracy),
        claim(cells, net, "on_path_fraction", False, on_path),
        claim(cells, net, "travel_time_s", True, fastest),
        *_faster_baselines(cells, net),
        claim(cells, net, "control_actions", False, more),
    ]
    fz = mean(cells, net, "fuzzy_pid", "on_path_fraction")
    bs = mean(cells, net, "backstepping", "on_path_fraction")
    verdict = "**matches**" if fz < bs else "**does not match**"
    out.append(
        f"- The immune fuzzy PID is on the optimal path less often than Backstepping "
        f"(paper 4/85 vs 29/62): {verdict} on the {net} network. Share on path "
        f"{fz:.2f} vs {bs:.2f}."
    )
    for ctrl in ("nurbs", *BASELINES):
        c = cells.get((net, ctrl))
        if c is not None and c.success.n and c.success.mean < 1.0:
            out.append(
                f"- Caution: {NAMES[ctrl]} reached the goal without contact and outside "
                f"the safety distance rho0 in only "
                f"{100 * c.success.mean:.0f} % of the runs on the {net} network, so its "
                "travel time and errors describe runs that failed the mission."
            )
    return out


def _faster_baselines(cells: Cells, net: str) -> list[str]:
    """For a baseline faster than NURBS: how its run differs (facts, no interpretation)."""
    out = []
    tn = mean(cells, net, "nurbs", "travel_time_s")
    for b in BASELINES:
        if mean(cells, net, b, "travel_time_s") < tn:
            diffs = ", ".join(
                f"{label} {mean(cells, net, b, m):.3g} vs {mean(cells, net, 'nurbs', m):.3g}"
                for m, label in (
                    ("path_length_m", "executed path length (m)"),
                    ("xte_optimal_rms_m", "XTE RMS (m)"),
                    ("min_clearance_m", "minimum clearance (m)"),
                    ("mean_speed_mps", "mean speed (m/s)"),
                )
            )
            out.append(
                f"  - {NAMES[b]} is faster than the NURBS method on the {net} network "
                f"({b} vs NURBS): {diffs}."
            )
    return out


def paper_table(cells: Cells, net: str) -> list[str]:
    """Our numbers beside the paper's (control actions, on path, travel time)."""
    lines = [
        "| controller | control actions: paper | ours | on optimal path: paper | ours | "
        "travel time: paper | ours |",
        "|---|---|---|---|---|---|---|",
    ]
    for ctrl in ("backstepping", "fuzzy_pid", "nurbs"):
        p = PAPER[ctrl]
        t = mean(cells, net, ctrl, "travel_time_s")
        on = "not stated" if p.on_path is None else str(p.on_path)
        lines.append(
            f"| {NAMES[ctrl]} | {p.controls} | {fmt(estimate(cells, net, ctrl, 'control_actions'))}"
            f" | {on} | {fmt(estimate(cells, net, ctrl, 'control_actions_on_path'))} | "
            f"{p.time_min} min | {fmt(estimate(cells, net, ctrl, 'travel_time_s'))} s "
            f"({t / 60:.2f} min) |"
        )
    return lines


def time_ratios(cells: Cells, net: str) -> str:
    """Baseline / NURBS travel-time ratios, ours and the paper's."""
    tn = mean(cells, net, "nurbs", "travel_time_s")
    parts = []
    for b in BASELINES:
        ours = mean(cells, net, b, "travel_time_s") / tn
        paper = PAPER[b].time_min / PAPER["nurbs"].time_min
        parts.append(f"{NAMES[b]} / NURBS = {ours:.2f} (paper {paper:.2f})")
    return "; ".join(parts)
