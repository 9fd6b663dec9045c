"""A fair gain search for the three controllers before the paper comparison.

Every controller gets the same procedure: its two principal path-following gains, each
scaled by powers of one step (x2 by default) around the scenario's values, run on a perfect
network with seeds disjoint from the evaluation seeds, each run setting only that
controller's gains. Each controller's search starts with the 3 x 3 box of factors 1/2, 1, 2
and widens its box in each direction where its choice lies on the edge, until the choice is
interior or the box reaches the search limit (factors 1/64 to 64 by default): a choice on
the edge of its grid says only that the grid was too small. The chosen candidate has the
highest success rate (goal reached, no contact, never inside rho0), then the lowest RMS
cross-track error to the path in force at each moment, then the shortest travel time. The
error to the path in force is the controller's own tracking error; the error to the first
("optimal") plan, which the report judges accuracy by, also counts the planner's decision to
re-route around an obstacle on its other side, which one or two tuning seeds make a noisy
criterion. No candidate is chosen to make a baseline fail: the baselines get exactly the
search the NURBS tracker gets.
"""

from __future__ import annotations

import itertools
import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common.config.controller import ControllerKind
from common.config.scenario import Scenario
from services.experiments.sweep.results import as_number
from services.experiments.sweep.schema import Axis, AxisValue, Experiment, SetValue

# the two gains of each controller that set how hard it steers back onto the path
TUNED_GAINS: dict[str, tuple[str, str]] = {
    # heading-error gain and look-ahead distance of the LOS approach angle
    "nurbs": ("controller.nurbs.k_heading_ps", "controller.nurbs.lookahead_m"),
    # Kanayama cross-track and heading gains
    "backstepping": ("controller.backstepping.k_y_pm2", "controller.backstepping.k_theta_pm"),
    # base proportional gain and the cross-track -> heading look-ahead
    "fuzzy_pid": ("controller.fuzzy_pid.kp_ps", "controller.fuzzy_pid.lookahead_m"),
}
# the accuracy criterion of the search: RMS cross-track error to the path in force
TUNING_XTE = "xte_planned_rms_m"
CONTROLLERS: tuple[ControllerKind, ...] = ("nurbs", "backstepping", "fuzzy_pid")
PERFECT_NETWORK: dict[str, SetValue] = {
    "network.default": {},
    "network.links": (),
    "network.outages": (),
}


Point = tuple[int, int]  # exponents (i_a, i_b): the candidate scales the gains by step**i


@dataclass(frozen=True, kw_only=True)
class Candidate:
    """One gain setting of one controller and how it did over the tuning seeds."""

    controller: str
    label: str
    point: Point
    gains: dict[str, float]
    runs: int
    success_rate: float
    xte_rms_m: float
    travel_time_s: float


@dataclass(frozen=True, kw_only=True)
class Box:
    """The exponents searched: i_a in [a_lo, a_hi], i_b in [b_lo, b_hi] (a rectangle)."""

    a_lo: int = -1
    a_hi: int = 1
    b_lo: int = -1
    b_hi: int = 1

    def points(self) -> list[Point]:
        return list(
            itertools.product(range(self.a_lo, self.a_hi + 1), range(self.b_lo, self.b_hi + 1))
        )

    def widened(self, best: dict[str, Candidate], limit: int) -> Box | None:
        """The box grown by one step in each direction where a choice lies on the edge (and
        the limit |i| <= limit allows it), or None when nothing can grow."""
        lo_a = any(c.point[0] == self.a_lo for c in best.values()) and self.a_lo > -limit
        hi_a = any(c.point[0] == self.a_hi for c in best.values()) and self.a_hi < limit
        lo_b = any(c.point[1] == self.b_lo for c in best.values()) and self.b_lo > -limit
        hi_b = any(c.point[1] == self.b_hi for c in best.values()) and self.b_hi < limit
        if not (lo_a or hi_a or lo_b or hi_b):
            return None
        return Box(
            a_lo=self.a_lo - lo_a,
            a_hi=self.a_hi + hi_a,
            b_lo=self.b_lo - lo_b,
            b_hi=self.b_hi + hi_b,
        )

    def edges(self, c: Candidate) -> list[str]:
        """Which of the candidate's gains sit on an edge of the box ('a', 'b')."""
        a, b = c.point
        return [
            n
            for n, on in (("a", a in (self.a_lo, self.a_hi)), ("b", b in (self.b_lo, self.b_hi)))
            if on
        ]


def gain_value(scenario: Scenario, key: str) -> float:
    """The scenario's value of a dotted controller key, e.g. controller.nurbs.lookahead_m."""
    node: Any = scenario
    for part in key.split("."):
        node = getattr(node, part)
    return float(node)


def point_label(point: Point, step: float) -> str:
    """'a0.5_b2': the factors of a point, as the tuning sweep's axis labels them."""
    return f"a{step ** point[0]:g}_b{step ** point[1]:g}"


def candidate_gains(scenario: Scenario, ctrl: str, point: Point, step: float) -> dict[str, float]:
    """A point of a controller's grid: its pair scaled by (step**i_a, step**i_b)."""
    a, b = TUNED_GAINS[ctrl]
    return {
        a: step ** point[0] * gain_value(scenario, a),
        b: step ** point[1] * gain_value(scenario, b),
    }


def tuning_experiment(
    scenario_path: str,
    scenario: Scenario,
    ctrl: ControllerKind,
    *,
    box: Box,
    step: float,
    seeds: int,
    first_seed: int,
    extra: dict[str, SetValue] | None = None,
) -> Experiment:
    """One controller's search as a sweep: axis 'gains' (the box's points), perfect network.

    Each run sets only that controller's gains (another's limits never refuse a point of
    this one's grid); `extra` are overrides for every run (the comparison's pipeline)."""
    values = tuple(
        AxisValue(label=point_label(pt, step), set=dict(candidate_gains(scenario, ctrl, pt, step)))
        for pt in box.points()
    )
    return Experiment(
        name=f"tune-{ctrl}",
        scenario=scenario_path,
        seeds=seeds,
        first_seed=first_seed,
        controllers=(ctrl,),
        set={**PERFECT_NETWORK, **(extra or {})},
        axes=(Axis(name="gains", values=values, x_label="gain factors (a, b)"),),
    )


def score(
    rows: list[dict[str, str]], exp: Experiment, ctrl: str, box: Box, step: float
) -> list[Candidate]:
    """Every point of one controller's box with its success rate, mean xte and travel time;
    `exp` is its tuning experiment (the 'gains' axis holds each point's gains)."""
    sets = {v.label: v.set for v in exp.axes[0].values}
    keys = TUNED_GAINS[ctrl]
    out = []
    for pt in box.points():
        label = point_label(pt, step)
        gains = sets[label]
        rs = [
            r
            for r in rows
            if r.get("controller") == ctrl and r.get("gains") == label and r.get("status") == "ok"
        ]
        succ = [as_number(r.get("success")) for r in rs]
        xte = [as_number(r.get(TUNING_XTE)) for r in rs]
        tt = [
            as_number(r.get("travel_time_s")) for r in rs if as_number(r.get("reached_goal")) == 1.0
        ]
        out.append(
            Candidate(
                controller=ctrl,
                label=label,
                point=pt,
                gains={k: _number(gains[k]) for k in keys},
                runs=len(rs),
                success_rate=_mean(succ),
                xte_rms_m=_mean(xte),
                travel_time_s=_mean(tt),
            )
        )
    return out


def _number(v: SetValue) -> float:
    if not isinstance(v, int | float):
        raise TypeError(f"a tuned gain must be a number, got {v!r}")
    return float(v)


def _mean(xs: list[float]) -> float:
    ys = [x for x in xs if math.isfinite(x)]
    return sum(ys) / len(ys) if ys else math.nan


def _rank(c: Candidate) -> tuple[float, float, float]:
    """Lower is better: most successes, then least cross-track error, then fastest."""

    def inf_if_nan(v: float) -> float:
        return v if math.isfinite(v) else math.inf

    return (
        -(c.success_rate if math.isfinite(c.success_rate) else -1.0),
        inf_if_nan(c.xte_rms_m),
        inf_if_nan(c.travel_time_s),
    )


def choose(candidates: list[Candidate]) -> dict[str, Candidate]:
    """The best candidate of each controller (ties keep grid order)."""
    best: dict[str, Candidate] = {}
    for c in candidates:
        if c.runs and (c.controller not in best or _rank(c) < _rank(best[c.controller])):
            best[c.controller] = c
    return best


def chosen_set(best: dict[str, Candidate]) -> dict[str, SetValue]:
    """The chosen gains of every controller as scenario overrides."""
    return {k: v for c in best.values() for k, v in c.gains.items()}


def save_choice(
    path: Path, best: dict[str, Candidate], boxes: dict[str, Box], step: float, seeds: list[int]
) -> None:
    """DIR/tuning/chosen.json: each controller's final box and choice, and the seeds."""
    doc = {
        "step": step,
        "seeds": seeds,
        "chosen": {
            k: {
                "label": c.label,
                "point": list(c.point),
                "box": {"a": [boxes[k].a_lo, boxes[k].a_hi], "b": [boxes[k].b_lo, boxes[k].b_hi]},
                "gains": c.gains,
                "on_edge": boxes[k].edges(c),
                "success_rate": c.success_rate,
                TUNING_XTE: c.xte_rms_m,
            }
            for k, c in best.items()
        },
    }
    path.write_text(json.dumps(doc, indent=2, allow_nan=True))


@dataclass(frozen=True, kw_only=True)
class Tuning:
    """The outcome of the gain search: every candidate, the choices, each final box."""

    best: dict[str, Candidate]
    candidates: list[Candidate]
    boxes: dict[str, Box]
    rounds: dict[str, int]
