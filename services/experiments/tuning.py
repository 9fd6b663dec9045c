"""A fair gain search for the three controllers before the paper comparison (`--tune`).

Every controller gets the same procedure: its two principal path-following gains, each
scaled by the same factors around the scenario's values (3 x 3 = 9 candidates by default),
run on a perfect network with seeds disjoint from the evaluation seeds. The chosen candidate
has the highest success rate (goal reached, no contact, never inside the safety distance
rho0), then the lowest RMS cross-track error to the path in force at each moment, then the
shortest travel time. The error to the
path in force is the controller's own tracking error; the error to the first ("optimal")
plan, which the report judges accuracy by, also counts the planner's decision to re-route
around an obstacle on its other side, which one or two tuning seeds make a noisy criterion.
No candidate is chosen to make a baseline fail: the baselines get exactly the search the
NURBS tracker gets.
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
from services.experiments.results import as_number
from services.experiments.schema import Axis, AxisValue, Experiment, SetValue

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


@dataclass(frozen=True, kw_only=True)
class Candidate:
    """One gain setting of one controller and how it did over the tuning seeds."""

    controller: str
    label: str
    gains: dict[str, float]
    runs: int
    success_rate: float
    xte_rms_m: float
    travel_time_s: float


def gain_value(scenario: Scenario, key: str) -> float:
    """The scenario's value of a dotted controller key, e.g. controller.nurbs.lookahead_m."""
    node: Any = scenario
    for part in key.split("."):
        node = getattr(node, part)
    return float(node)


def candidate_gains(scenario: Scenario, factors: tuple[float, ...]) -> list[dict[str, float]]:
    """The grid: candidate i sets every controller's pair to (f_a * a0, f_b * b0)."""
    out = []
    for fa, fb in itertools.product(factors, factors):
        g: dict[str, float] = {}
        for a, b in TUNED_GAINS.values():
            g[a] = fa * gain_value(scenario, a)
            g[b] = fb * gain_value(scenario, b)
        out.append(g)
    return out


def tuning_experiment(
    scenario_path: str,
    scenario: Scenario,
    *,
    seeds: int,
    first_seed: int,
    factors: tuple[float, ...],
    extra: dict[str, SetValue] | None = None,
) -> Experiment:
    """The search as a sweep: axis 'gains' (factor pairs) x controllers, perfect network.

    `extra` are overrides for every run (the comparison's planning mode).
    """
    values = []
    for (fa, fb), g in zip(
        itertools.product(factors, factors), candidate_gains(scenario, factors), strict=True
    ):
        values.append(AxisValue(label=f"a{fa:g}_b{fb:g}", set=dict(g)))
    return Experiment(
        name="tune",
        scenario=scenario_path,
        seeds=seeds,
        first_seed=first_seed,
        controllers=CONTROLLERS,
        set={**PERFECT_NETWORK, **(extra or {})},
        axes=(Axis(name="gains", values=tuple(values), x_label="gain factors (a, b)"),),
    )


def score(rows: list[dict[str, str]], exp: Experiment) -> list[Candidate]:
    """Every (controller, candidate) with its success rate, mean xte and travel time."""
    gains_axis = exp.axes[0]
    out = []
    for ctrl in CONTROLLERS:
        keys = TUNED_GAINS[ctrl]
        for v in gains_axis.values:
            rs = [
                r
                for r in rows
                if r.get("controller") == ctrl
                and r.get("gains") == v.label
                and r.get("status") == "ok"
            ]
            succ = [as_number(r.get("success")) for r in rs]
            xte = [as_number(r.get(TUNING_XTE)) for r in rs]
            tt = [
                as_number(r.get("travel_time_s"))
                for r in rs
                if as_number(r.get("reached_goal")) == 1.0
            ]
            out.append(
                Candidate(
                    controller=ctrl,
                    label=v.label,
                    gains={k: _number(v.set[k]) for k in keys},
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
    path: Path, best: dict[str, Candidate], factors: tuple[float, ...], seeds: list[int]
) -> None:
    doc = {
        "factors": list(factors),
        "seeds": seeds,
        "chosen": {
            k: {
                "label": c.label,
                "gains": c.gains,
                "success_rate": c.success_rate,
                TUNING_XTE: c.xte_rms_m,
            }
            for k, c in best.items()
        },
    }
    path.write_text(json.dumps(doc, indent=2, allow_nan=True))
