"""`tidelink reproduce` on the small scenario: gain search, comparison, REPORT.md, figures."""

from __future__ import annotations

import json
import re
from pathlib import Path

from common.config.scenario import load_scenario
from services.experiments.reproduce import ReproduceOptions, reproduce
from services.experiments.tuning import TUNED_GAINS, Candidate, candidate_gains, choose

ROOT = Path(__file__).resolve().parents[1]
SMALL = ROOT / "configs" / "experiments" / "scenarios" / "small.toml"


def test_reproduce_writes_the_report_tables_and_figures(tmp_path: Path) -> None:
    opts = ReproduceOptions(
        out=tmp_path,
        scenario=SMALL,
        seeds=1,
        runtime="inproc",
        jobs=2,
        tune=True,
        tune_seeds=1,
        tune_factors=(1.0,),
        rich=False,
    )
    res = reproduce(opts)
    assert (res.sweep.total, res.sweep.errors) == (6, 0)  # 2 networks x 3 controllers x 1 seed
    assert res.tuned is not None and set(res.tuned) == {"nurbs", "backstepping", "fuzzy_pid"}
    chosen = json.loads((tmp_path / "tuning" / "chosen.json").read_text())
    assert chosen["seeds"] == [101] and set(chosen["chosen"]) == set(TUNED_GAINS)
    text = res.report.read_text()
    for heading in (
        "## Gains",
        "## Results: perfect network",
        "## Results: lossy network",
        "## Beside the paper",
        "## The paper's qualitative claims",
        "## Figures",
    ):
        assert heading in text
    # the paper's numbers beside ours, and the on-path tolerance stated
    for paper in (
        "| 62 |",
        "| 29 |",
        "| 85 |",
        "| 4 |",
        "| 100 |",
        "21.89 min",
        "32.5 min",
        "4.98 min",
        "within 0.5 m",
    ):
        assert paper in text, paper
    assert (
        text.count("**matches")
        + text.count("**partly matches**")
        + text.count("**does not match**")
        == 10
    )  # five claims judged on each of the two networks
    assert "Planning: the first plan is kept" in text
    # the paper's setup: one planned path per run, followed by every controller
    assert {r["replans"] for r in res.sweep.rows} == {"1"}
    figs = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", text)
    assert len(figs) == 10  # figures 2-6 for each network
    for f in figs:
        assert (tmp_path / f).read_bytes()[:4] == b"\x89PNG"


def test_the_gain_grid_is_the_same_for_every_controller() -> None:
    s, _ = load_scenario(SMALL)
    grid = candidate_gains(s, (0.5, 1.0, 2.0))
    assert len(grid) == 9
    base = candidate_gains(s, (1.0,))[0]
    for ctrl, (a, b) in TUNED_GAINS.items():
        ratios = sorted((g[a] / base[a], g[b] / base[b]) for g in grid)
        assert ratios == sorted((fa, fb) for fa in (0.5, 1.0, 2.0) for fb in (0.5, 1.0, 2.0)), ctrl


def _cand(ctrl: str, label: str, succ: float, xte: float, tt: float = 60.0) -> Candidate:
    return Candidate(
        controller=ctrl,
        label=label,
        gains={},
        runs=2,
        success_rate=succ,
        xte_rms_m=xte,
        travel_time_s=tt,
    )


def test_choice_prefers_success_then_accuracy_then_speed() -> None:
    best = choose(
        [
            _cand("nurbs", "fast-but-crashes", 0.5, 0.1, 40.0),
            _cand("nurbs", "safe", 1.0, 0.3),
            _cand("nurbs", "safe-and-accurate", 1.0, 0.2),
            _cand("fuzzy_pid", "a", 1.0, 0.2, 70.0),
            _cand("fuzzy_pid", "b", 1.0, 0.2, 65.0),
            _cand("backstepping", "never-arrives", 0.0, float("nan")),
        ]
    )
    assert best["nurbs"].label == "safe-and-accurate"
    assert best["fuzzy_pid"].label == "b"
    assert best["backstepping"].label == "never-arrives"  # every controller gets a choice
