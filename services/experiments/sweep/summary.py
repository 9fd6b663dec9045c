"""Per-cell statistics of a sweep and DIR/summary.md + DIR/summary.csv."""

from __future__ import annotations

import csv
import math
from dataclasses import dataclass, field
from pathlib import Path

from services.experiments.sweep.markdown import blocks, document, section, table
from services.experiments.sweep.results import LEAD, TAIL_FACTS, as_number
from services.experiments.sweep.stats import (
    FEW_SEEDS,
    Estimate,
    bootstrap_ci,
    proportion_ci,
    wilson,
)
from services.mission.outcome import OUTCOMES, classify

# the columns summary.md shows for every cell (all metrics are in summary.csv)
KEY_METRICS = (
    "travel_time_s",
    "path_length_m",
    "xte_optimal_rms_m",
    "min_clearance_m",
    "collisions",
    "time_below_rho0_s",
    "time_above_curvature_limit_s",
    "path_reentries",
    "control_actions",
    "control_actions_on_path",
    "on_path_fraction",
    "commands_rejected_stale",
    "net_delivery_ratio",
    # fleets (services/mission/fleet_metrics.py)
    "vehicles_reached",
    "min_separation_m",
    "vehicle_collisions",
    "intent_fraction",
)
# eq. (21) travel time only means something for runs that arrived
ON_GOAL_ONLY = frozenset({"travel_time_s", "mean_speed_mps"})
# the failures summary.md counts in a column each (success has its rate)
FAILURES = tuple(o for o in OUTCOMES if o != "success")
NOT_METRICS = frozenset(
    {
        *LEAD,
        *TAIL_FACTS,
        "trajectory_sha256",
        "controller",
        "end_reason",
        "success",
        "outcome",
        "rho0_m",  # the safety distance judged against: a setting, not a measurement
    }
)


@dataclass(frozen=True, kw_only=True)
class CellStats:
    """One grid cell over its seeds: counts, success rate, how many runs ended in each
    outcome (services/mission/outcome.py) and every metric's estimate."""

    labels: dict[str, str]
    n_runs: int
    n_errors: int
    success: Estimate
    metrics: dict[str, Estimate]
    # runs per outcome, every outcome present (0 if none), over the runs that have one
    outcomes: dict[str, int] = field(default_factory=dict)

    @property
    def n_judged(self) -> int:
        """Runs with an outcome."""
        return sum(self.outcomes.values())


def metric_names(rows: list[dict[str, str]], grid: tuple[str, ...]) -> list[str]:
    """Numeric columns of successful rows, sorted; grid and bookkeeping columns excluded."""
    names: set[str] = set()
    for r in rows:
        if r.get("status") != "ok":
            continue
        for k, v in r.items():
            if k not in NOT_METRICS and k not in grid and math.isfinite(as_number(v)):
                names.add(k)
    return sorted(names)


def aggregate(rows: list[dict[str, str]], grid: tuple[str, ...]) -> list[CellStats]:
    """Group rows by their grid labels (first-seen order) and estimate every metric."""
    groups: dict[tuple[str, ...], list[dict[str, str]]] = {}
    for r in rows:
        groups.setdefault(tuple(r.get(g, "") for g in grid), []).append(r)
    names = metric_names(rows, grid)
    out = []
    for key, rs in groups.items():
        ok = [r for r in rs if r.get("status") == "ok"]
        goal = [r for r in ok if as_number(r.get("reached_goal")) == 1.0]
        wins = sum(1 for r in ok if as_number(r.get("success")) == 1.0)
        metrics = {
            m: estimate([r.get(m) for r in (goal if m in ON_GOAL_ONLY else ok)]) for m in names
        }
        ends = [row_outcome(r) for r in ok]
        out.append(
            CellStats(
                labels=dict(zip(grid, key, strict=True)),
                n_runs=len(rs),
                n_errors=len(rs) - len(ok),
                success=wilson(wins, len(ok)),
                metrics=metrics,
                outcomes={o: ends.count(o) for o in OUTCOMES},
            )
        )
    return out


def estimate(cells: list[str | None]) -> Estimate:
    """A metric's mean over a cell's runs with an interval within its bounds: Wilson's for
    a True/False column (a proportion of runs), else the bootstrap percentile interval
    (stats.py)."""
    given = [c for c in cells if c not in (None, "")]
    values = [as_number(c) for c in given]
    if given and all(c in ("True", "False") for c in given):
        return proportion_ci(values)
    return bootstrap_ci(values)


def few_seeds(cells: list[CellStats]) -> list[CellStats]:
    """The cells whose statistics rest on fewer than FEW_SEEDS runs (of those that ran)."""
    return [c for c in cells if c.n_runs - c.n_errors < FEW_SEEDS]


def row_outcome(r: dict[str, str]) -> str | None:
    """A results.csv row's outcome; None if its mission does not judge runs. A row of a sweep
    older than the `outcome` column (a sweep resumed) is judged here, the one place that
    reads such rows: by its `success`, and without it by what success was made of (no
    contact and at the goal, yet no success: only the safety distance is left)."""
    stated = r.get("outcome")
    if stated in OUTCOMES:
        return stated
    if not math.isfinite(as_number(r.get("success"))):
        return None

    def said(key: str) -> bool:  # a True (or non-zero) cell
        v = as_number(r.get(key))
        return math.isfinite(v) and v != 0.0

    if said("success"):
        return "success"
    return classify(reached_goal=said("reached_goal"), contact=said("collisions"), below_rho0=True)


def success_text(e: Estimate) -> str:
    if e.n == 0:
        return "–"
    return f"{100 * e.mean:.0f} % [{100 * e.low:.0f}, {100 * e.high:.0f}]"


def outcome_text(c: CellStats, outcome: str) -> str:
    """How many of a cell's judged runs ended in this outcome, "k/n"."""
    return f"{c.outcomes.get(outcome, 0)}/{c.n_judged}" if c.n_judged else "–"


def _few_seeds_warning(cells: list[CellStats], grid: tuple[str, ...]) -> str:
    """summary.md's warning about cells of fewer than FEW_SEEDS runs ("" if none)."""
    few = few_seeds(cells)
    if not few:
        return ""
    names = [", ".join(f"{g}={c.labels[g]}" for g in grid) or "all runs" for c in few]
    counts = sorted({c.n_runs - c.n_errors for c in few})
    shown = "; ".join(names[:6]) + (f"; and {len(names) - 6} more" if len(names) > 6 else "")
    return (
        f"> **Warning: {len(few)} of {len(cells)} cells rest on fewer than {FEW_SEEDS} runs** "
        f"({' or '.join(map(str, counts))}; marked ⚠): {shown}. Their intervals are rough: "
        "from so few seeds a bootstrap interval misses the true mean more often than 5 % of "
        "the time, and a rate of 0 % or 100 % says little. Run more seeds (the experiment "
        "file's `seeds`) before reading differences between them."
    )


READING = (
    "Success = reached the goal without contact and never inside the safety distance "
    "rho0 (Wilson 95 % interval). The failures are counted by outcome (of the runs "
    "judged): rho0_breach = goal reached without contact but inside rho0, collision = "
    "any contact, not_reached = no contact, goal not reached. Other columns: mean "
    "[95 % interval] over the seeds, the bootstrap percentile interval of the mean "
    "(within the values' range: never below 0 for a quantity that cannot be; Wilson's "
    "for a True/False column); travel_time_s only over runs that reached the goal."
)


def _cell_name(labels: dict[str, str], grid: tuple[str, ...]) -> str:
    return ", ".join(f"{g}={labels.get(g, '')}" for g in grid)


def _key_metrics(cells: list[CellStats], grid: tuple[str, ...]) -> list[str]:
    """One row per cell: runs (⚠ when few), errors, success, failures, the key metrics."""
    keys = [m for m in KEY_METRICS if any(m in c.metrics for c in cells)]
    rough = {id(c) for c in few_seeds(cells)}
    rows = [
        [
            *(c.labels[g] for g in grid),
            f"{c.n_runs}{' ⚠' if id(c) in rough else ''}",
            str(c.n_errors),
            success_text(c.success),
            *(outcome_text(c, o) for o in FAILURES),
            *(c.metrics[m].text() if m in c.metrics else "–" for m in keys),
        ]
        for c in cells
    ]
    return table([*grid, "runs", "errors", "success", *FAILURES, *keys], rows)


def _failed_runs(errors: list[dict[str, str]], grid: tuple[str, ...]) -> list[str]:
    """The runs that failed to execute, with their error ("|" made "/", 200 characters)."""
    if not errors:
        return []
    rows = [
        [
            r["run_id"],
            _cell_name(r, grid),
            r.get("seed", ""),
            r.get("error", "").replace("|", "/")[:200],
        ]
        for r in errors
    ]
    return section("Failed runs", table(["run_id", "cell", "seed", "error"], rows))


def _every_metric(c: CellStats, grid: tuple[str, ...]) -> list[str]:
    """One cell's every metric, folded away in a <details> block."""
    rows = [
        [m, f"{e.mean:.4g}", f"[{e.low:.4g}, {e.high:.4g}]" if e.n >= 2 else "–", str(e.n)]
        for m, e in c.metrics.items()
    ]
    name = _cell_name(c.labels, grid) or "all runs"
    return blocks(
        f"<details><summary>{name}</summary>",
        table(["metric", "mean", "95 % CI", "n"], rows),
        "</details>",
    )


def _write_csv(path: Path, cells: list[CellStats], grid: tuple[str, ...]) -> None:
    """summary.csv: per cell, the success rate, each outcome's rate and every metric."""
    with path.open("w", newline="") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow([*grid, "metric", "mean", "ci_low", "ci_high", "n"])
        for c in cells:
            lab = [c.labels[g] for g in grid]
            w.writerow(
                [*lab, "success_rate", c.success.mean, c.success.low, c.success.high, c.success.n]
            )
            for o, k in c.outcomes.items():  # each outcome's share, with its Wilson interval
                if c.n_judged:
                    e = wilson(k, c.n_judged)
                    w.writerow([*lab, f"outcome_{o}_rate", e.mean, e.low, e.high, e.n])
            for m, e in c.metrics.items():
                w.writerow([*lab, m, e.mean, e.low, e.high, e.n])


def write_summary(
    out: Path,
    title: str,
    intro: str,
    cells: list[CellStats],
    grid: tuple[str, ...],
    errors: list[dict[str, str]],
) -> None:
    """summary.md (key metrics per cell, errors, every metric per cell) and summary.csv."""
    text = document(
        section(title, intro, READING, _few_seeds_warning(cells, grid), level=1),
        section("Key metrics", _key_metrics(cells, grid)),
        _failed_runs(errors, grid),
        section("Every metric", *(_every_metric(c, grid) for c in cells)),
    )
    (out / "summary.md").write_text(text)
    _write_csv(out / "summary.csv", cells, grid)
