"""results.csv durability (torn rows, growing header) and the confidence intervals."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from services.experiments.reproduction.claims import compare
from services.experiments.sweep.results import ResultsFile, as_number
from services.experiments.sweep.stats import Estimate, bootstrap_ci, proportion_ci, wilson
from services.experiments.sweep.summary import FAILURES, aggregate, write_summary


def _row(i: int, **extra: object) -> dict[str, object]:
    return {"run_id": f"r{i}", "status": "ok", "seed": i, "net": "a", **extra}


def test_rows_survive_a_reload_and_a_torn_last_line_is_cut(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    f = ResultsFile(path, grid_columns=("net",))
    for i in range(3):
        f.append(_row(i, x=0.1 * i, reached_goal=True))
    whole = path.read_bytes()
    path.write_bytes(whole + b"r3,ok,3,a,0.3")  # a kill in the middle of writing row 4
    again = ResultsFile(path, grid_columns=("net",))
    assert again.ids() == {"r0", "r1", "r2"}
    assert path.read_bytes() == whole  # the torn row is gone, the others untouched
    again.append(_row(3, x=0.3, reached_goal=False))
    rows = list(csv.DictReader(path.open()))
    assert [r["run_id"] for r in rows] == ["r0", "r1", "r2", "r3"]
    assert as_number(rows[3]["reached_goal"]) == 0.0 and float(rows[2]["x"]) == 0.2


def test_a_new_metric_widens_the_header_without_losing_rows(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    f = ResultsFile(path, grid_columns=("net",))
    f.append(_row(0, error=""))
    f.append(_row(1, y=2.5, error="boom\nline two"))
    rows = list(csv.DictReader(path.open()))
    assert rows[0]["run_id"] == "r0" and rows[0]["y"] == ""
    assert rows[1]["y"] == "2.5" and rows[1]["error"] == "boom | line two"  # one line per row
    assert path.read_text().count("\n") == 3
    assert next(iter(csv.reader(path.open())))[:4] == ["run_id", "status", "seed", "net"]


def test_dropping_failed_rows_rewrites_the_file(tmp_path: Path) -> None:
    path = tmp_path / "results.csv"
    f = ResultsFile(path)
    f.append(_row(0))
    f.append({"run_id": "r1", "status": "error", "error": "x"})
    f.drop(f.ids("error"))
    assert ResultsFile(path).ids() == {"r0"}


def test_a_non_negative_quantity_never_gets_a_negative_bound() -> None:
    # issue 61: three seeds of rho0_breach_m, mostly 0; the t-interval went to [-0.35, 0.67]
    from scipy import stats  # here: a second of import for every process that collects

    breach = [0.0, 0.0, 0.47]
    lo, _ = stats.t.interval(0.95, 2, loc=np.mean(breach), scale=stats.sem(breach))
    assert lo < 0.0  # what the summary used to show
    e = bootstrap_ci(breach)
    assert e.n == 3 and e.mean == pytest.approx(0.47 / 3)
    assert 0.0 <= e.low <= e.mean <= e.high <= 0.47
    assert math.isnan(bootstrap_ci([5.0]).low) and bootstrap_ci([]).n == 0
    assert bootstrap_ci([1.0, float("nan"), 3.0]).n == 2  # missing values are not zeros


def test_the_bootstrap_interval_is_the_same_for_the_same_values() -> None:
    xs = [3.1, 2.7, 8.4, 0.2, 5.5]
    assert bootstrap_ci(xs) == bootstrap_ci(list(xs))  # a regenerated summary is the same


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1e6, 1e6), min_size=2, max_size=40))
def test_the_bootstrap_interval_lies_within_the_values_around_their_mean(xs: list[float]) -> None:
    e = bootstrap_ci(xs)
    assert min(xs) <= e.low <= e.mean <= e.high <= max(xs)
    if min(xs) >= 0.0:
        assert e.low >= 0.0


def test_the_bootstrap_interval_of_many_seeds_is_near_the_t_interval() -> None:
    # for 40 roughly normal values both are sound: they must agree to a few per cent
    from scipy import stats

    xs = list(np.random.default_rng(7).normal(10.0, 2.0, 40))
    e = bootstrap_ci(xs)
    lo, hi = stats.t.interval(0.95, len(xs) - 1, loc=np.mean(xs), scale=stats.sem(xs))
    assert e.low == pytest.approx(lo, abs=0.1 * (hi - lo))
    assert e.high == pytest.approx(hi, abs=0.1 * (hi - lo))


def test_a_true_false_column_is_a_proportion_with_wilsons_interval() -> None:
    rows = [
        {"run_id": str(i), "status": "ok", "g": "a", "reached_goal": str(i < 2), "x": str(i)}
        for i in range(3)
    ]
    (a,) = aggregate(rows, ("g",))
    assert a.metrics["reached_goal"] == wilson(2, 3)
    assert a.metrics["x"] == bootstrap_ci([0.0, 1.0, 2.0])
    assert proportion_ci([1.0, 0.0, float("nan")]) == wilson(1, 2)


@given(st.integers(1, 200).flatmap(lambda n: st.tuples(st.integers(0, n), st.just(n))))
def test_wilson_interval_contains_the_rate_and_stays_in_0_1(kn: tuple[int, int]) -> None:
    k, n = kn
    e = wilson(k, n)
    assert 0.0 <= e.low <= e.mean <= e.high <= 1.0
    assert e.high - e.low > 0.0  # never a zero-width claim from finite data


def test_wilson_known_value() -> None:
    e = wilson(3, 3)  # 3 of 3: [0.438, 1.0] at 95 %
    assert e.mean == 1.0 and e.low == pytest.approx(0.4385, abs=1e-4) and e.high == 1.0


def test_aggregate_groups_cells_and_conditions_travel_time_on_the_goal() -> None:
    rows = [
        {
            "run_id": "1",
            "status": "ok",
            "g": "a",
            "success": "True",
            "reached_goal": "True",
            "travel_time_s": "10.0",
            "xte": "1.0",
        },
        {
            "run_id": "2",
            "status": "ok",
            "g": "a",
            "success": "False",
            "reached_goal": "False",
            "travel_time_s": "200.0",
            "xte": "3.0",
        },
        {"run_id": "3", "status": "error", "g": "a", "error": "boom"},
        {
            "run_id": "4",
            "status": "ok",
            "g": "b",
            "success": "True",
            "reached_goal": "True",
            "travel_time_s": "12.0",
            "xte": "2.0",
        },
    ]
    a, b = aggregate(rows, ("g",))
    assert (a.labels, a.n_runs, a.n_errors) == ({"g": "a"}, 3, 1)
    assert a.success.mean == 0.5 and a.success.n == 2
    assert a.metrics["travel_time_s"].mean == 10.0  # the failed run's 200 s is not a travel time
    assert a.metrics["xte"].mean == 2.0 and b.metrics["xte"].n == 1


def test_aggregate_counts_each_outcome_and_the_summary_shows_them(tmp_path: Path) -> None:
    ends = ["success", "rho0_breach", "rho0_breach", "collision", "not_reached", "success"]
    rows = [
        {
            "run_id": str(i),
            "status": "ok",
            "ctrl": "a" if i < 4 else "b",
            "outcome": end,
            "success": str(end == "success"),
            "reached_goal": str(end in ("success", "rho0_breach")),
            "rho0_m": "1.0",
            "time_below_rho0_s": "2.0" if end != "success" else "0.0",
        }
        for i, end in enumerate(ends)
    ]
    # a row of an older sweep, without the column: judged by its success and its parts
    rows.append(
        {"run_id": "old", "status": "ok", "ctrl": "b", "success": "False", "reached_goal": "False"}
    )
    rows.append({"run_id": "err", "status": "error", "ctrl": "b", "error": "boom"})
    a, b = aggregate(rows, ("ctrl",))
    assert a.outcomes == {"success": 1, "rho0_breach": 2, "collision": 1, "not_reached": 0}
    assert b.outcomes == {"success": 1, "rho0_breach": 0, "collision": 0, "not_reached": 2}
    assert (a.n_judged, b.n_judged, b.n_runs, b.n_errors) == (4, 3, 4, 1)
    assert a.success.mean == 0.25 and b.success.n == 3
    assert "rho0_m" not in a.metrics and "outcome" not in a.metrics  # a setting, a word
    assert a.metrics["time_below_rho0_s"].mean == 1.5
    write_summary(tmp_path, "t", "intro", [a, b], ("ctrl",), [])
    table = (tmp_path / "summary.md").read_text().splitlines()
    head = next(line for line in table if line.startswith("| ctrl |"))
    cols = [c.strip() for c in head.strip("|").split("|")]
    assert cols[:7] == ["ctrl", "runs", "errors", "success", *FAILURES]
    assert FAILURES == ("rho0_breach", "collision", "not_reached")
    row_a = next(line for line in table if line.startswith("| a |"))
    below = a.metrics["time_below_rho0_s"].text()
    assert [c.strip() for c in row_a.strip("|").split("|")][4:8] == ["2/4", "1/4", "0/4", below]
    with (tmp_path / "summary.csv").open() as fh:
        got = {(r["ctrl"], r["metric"]): r for r in csv.DictReader(fh)}
    share = got[("a", "outcome_rho0_breach_rate")]
    assert float(share["mean"]) == 0.5 and share["n"] == "4"
    assert float(share["ci_low"]) < 0.5 < float(share["ci_high"])  # Wilson, as success_rate
    assert float(got[("b", "outcome_not_reached_rate")]["mean"]) == pytest.approx(2 / 3)


def test_compare_says_which_side_and_whether_intervals_separate() -> None:
    def est(m: float, h: float) -> Estimate:
        return Estimate(mean=m, low=m - h, high=m + h, n=3)

    assert compare(est(1.0, 0.1), est(2.0, 0.1), nurbs_lower=True) == "yes"
    assert compare(est(1.0, 0.8), est(2.0, 0.8), nurbs_lower=True) == "yes, CIs overlap"
    assert compare(est(3.0, 0.1), est(2.0, 0.1), nurbs_lower=True) == "no"
    assert compare(est(3.0, 0.1), est(2.0, 0.1), nurbs_lower=False) == "yes"
    assert compare(None, est(2.0, 0.1), nurbs_lower=True) == "n/a"


def test_progress_prints_plain_lines_or_a_rich_bar() -> None:
    import io

    from services.experiments.sweep.progress import SweepProgress

    plain = io.StringIO()
    with SweepProgress(2, stream=plain, rich=False) as p:
        p.done("cell a", ok=True)
        p.done("cell b", ok=False)
    lines = plain.getvalue().splitlines()
    assert lines[0].startswith("[1/2] ok cell a") and "eta 0:00:" in lines[0]
    assert lines[1].startswith("[2/2] ERROR cell b") and lines[1].endswith("eta 0:00:00)")
    bar = io.StringIO()
    with SweepProgress(3, stream=bar, rich=True, title="sweep t") as p:
        for _ in range(3):
            p.done("x", ok=True)
    assert "sweep t" in bar.getvalue() and "3/3" in bar.getvalue()


def _cell_rows(label: str, n: int) -> list[dict[str, str]]:
    return [
        {
            "run_id": f"{label}{i}",
            "status": "ok",
            "g": label,
            "success": "True",
            "reached_goal": "True",
            "rho0_breach_m": "0.0" if i % 3 else "0.5",
        }
        for i in range(n)
    ]


def test_the_summary_warns_of_cells_with_fewer_than_10_seeds(tmp_path: Path) -> None:
    cells = aggregate(_cell_rows("few", 3) + _cell_rows("many", 10), ("g",))
    write_summary(tmp_path, "t", "intro", cells, ("g",), [])
    text = (tmp_path / "summary.md").read_text()
    warning = next(line for line in text.splitlines() if "Warning" in line)
    assert "1 of 2 cells rest on fewer than 10 runs** (3; marked ⚠): g=few." in warning
    assert "| few | 3 ⚠ | 0 |" in text and "| many | 10 | 0 |" in text
    # every interval of the non-negative breach is non-negative, in both tables
    assert "-" not in next(line for line in text.splitlines() if "| rho0_breach_m |" in line)
    with (tmp_path / "summary.csv").open() as fh:
        lows = [float(r["ci_low"]) for r in csv.DictReader(fh) if r["metric"] == "rho0_breach_m"]
    assert lows and min(lows) >= 0.0


def test_no_warning_when_every_cell_has_10_seeds(tmp_path: Path) -> None:
    write_summary(tmp_path, "t", "intro", aggregate(_cell_rows("a", 10), ("g",)), ("g",), [])
    text = (tmp_path / "summary.md").read_text()
    assert "Warning" not in text and "⚠" not in text
