"""run.png's paths: bold, the part of each plan that was in force as the vehicle flew it; faint,
every plan whole; each replan marked with its reason's first word. A run that flew the second
plan must not look off its path because the first one is drawn bold."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from helpers.launch_proc import REPO

from common.config.scenario import load_scenario
from common.messages import PathMsg, TruthState
from common.runtime.model.record import Record
from services.launcher.plot import reason_word, replan_labels, run_figure

DEFAULT = REPO / "configs" / "default.toml"
FLOWN = "path in force, as flown"


def _line(path_id: int, stamp: float, a: tuple[float, float], b: tuple[float, float], why: str):
    """A straight plan from a to b (a degree-1 NURBS), published at `stamp`."""
    return PathMsg(
        stamp=stamp, seq=path_id, source="planner", path_id=path_id, status="OK", reason=why,
        degree=1, control_points=(*a, *b), weights=(1.0, 1.0), knots=(0.0, 0.0, 1.0, 1.0),
        waypoints=(*a, *b), length=float(np.hypot(b[0] - a[0], b[1] - a[1])), f_l=1.0,
        max_curvature=0.0, v_ref=1.0,
    )  # fmt: skip


def _record() -> Record:
    """Plan 1 east along y = 20 from x = 5; at t = 5 s (x = 10) plan 2 turns north-east, which
    the vehicle flies to t = 20 s; at t = 20 s (10 m further on it) plan 3, a detour, takes over
    for the rest; two more replans of one reason a metre apart."""
    rec = Record()
    plans = [
        _line(1, 0.0, (5.0, 20.0), (95.0, 20.0), "no_path"),
        _line(2, 5.0, (10.0, 20.0), (40.0, 35.0), "infeasible: hull would touch obstacle 4"),
        _line(3, 20.0, (23.4, 26.7), (60.0, 26.7), "current"),
        _line(4, 20.5, (24.0, 26.7), (60.0, 26.7), "current"),
    ]
    for p in plans:
        rec.add("planner", "path", p)
    for i in range(61):  # 1 m/s along plan 1 then 2 then 3 (0.5 s steps)
        t = 0.5 * i
        if t < 5.0:
            x, y = 5.0 + t, 20.0
        elif t < 20.0:
            d = (t - 5.0) / np.hypot(30.0, 15.0)
            x, y = 10.0 + 30.0 * d, 20.0 + 15.0 * d
        else:
            x, y = 23.4 + (t - 20.0), 26.7
        rec.add("vehicle", "truth", TruthState(
            stamp=t, source="vehicle", seq=i + 1, x=float(x), y=float(y), theta=0.0, v=1.0, w=0.0,
        ))  # fmt: skip
    return rec


def _lines(ax: Any, label: str) -> list[Any]:
    """The plotted lines in the legend under `label`, and those drawn in the same style."""
    (first,) = [ln for ln in ax.lines if ln.get_label() == label]
    return [
        ln for ln in ax.lines
        if ln.get_linewidth() == first.get_linewidth() and ln.get_alpha() == first.get_alpha()
        and ln.get_color() == first.get_color() and len(ln.get_xdata()) > 1
    ]  # fmt: skip


def test_the_bold_line_is_the_path_flown_and_every_plan_is_faint_whole() -> None:
    scenario, _ = load_scenario(DEFAULT)
    ax = run_figure(_record(), scenario).axes[0]
    bold = _lines(ax, FLOWN)
    faint = _lines(ax, "planned paths, as planned")
    assert len(faint) == 4  # every plan, whole
    assert min(ln.get_linewidth() for ln in bold) > 2 * max(ln.get_linewidth() for ln in faint)
    truth = next(ln for ln in ax.lines if ln.get_label() == "true trajectory")
    assert min(ln.get_linewidth() for ln in bold) > truth.get_linewidth()
    # plan 1 in force from x = 5 to 10, plan 2 from (10, 20) to (23.4, 26.7), plan 4 after
    # (plan 3 was replaced half a second on, the vehicle hardly on it)
    spans = [(ln.get_xdata()[0], ln.get_xdata()[-1]) for ln in bold]
    assert spans[0] == pytest.approx((5.0, 10.0), abs=0.3)
    assert spans[1] == pytest.approx((10.0, 23.4), abs=0.3)
    assert spans[-1] == pytest.approx((24.0, 33.4), abs=0.3)
    # every bold point lies on the true track: the vehicle is never drawn off its path
    track = np.column_stack([truth.get_xdata(), truth.get_ydata()])
    for ln in bold:
        pts = np.column_stack([ln.get_xdata(), ln.get_ydata()])
        gaps = np.min(np.hypot(*(pts[:, None, :] - track[None, :, :]).transpose(2, 0, 1)), 1)
        assert gaps.max() < 0.6


def test_each_replan_is_marked_with_its_reasons_first_word() -> None:
    scenario, _ = load_scenario(DEFAULT)
    ax = run_figure(_record(), scenario).axes[0]
    texts = [t.get_text() for t in ax.texts]
    assert "infeasible" in texts and "current x2" in texts  # two of one reason, 0.6 m apart
    assert "no_path" not in texts  # the first plan is no replan


def test_a_reasons_first_word() -> None:
    assert reason_word("deviation: 2.3 m off the path") == "deviation"
    assert reason_word("infeasible, 0.3 m into rho0") == "infeasible"
    assert reason_word("goal_changed") == "goal_changed"
    assert reason_word("") == "replan"


def test_replans_of_one_reason_far_apart_are_labelled_apart() -> None:
    a = _line(2, 1.0, (0.0, 0.0), (10.0, 0.0), "current")
    b = _line(3, 2.0, (30.0, 0.0), (40.0, 0.0), "current")
    c = _line(4, 3.0, (31.0, 0.0), (40.0, 0.0), "deviation")
    first = _line(1, 0.0, (0.0, 0.0), (1.0, 0.0), "no_path")
    drawn = [(p, np.array([p.control_points[:2], p.control_points[2:]])) for p in (first, a, b, c)]
    assert [text for _, text in replan_labels(drawn)] == ["current", "current", "deviation"]
