"""PlannerConfig: defaults are valid, bad values are rejected with the field's name."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.planner import PlannerConfig

DEFAULT = Path(__file__).resolve().parents[1] / "configs" / "default.toml"


def test_defaults_are_valid_and_documented_values() -> None:
    cfg = PlannerConfig()
    assert cfg.resolution_m == 0.5 and cfg.rho0_m == 1.0 and cfg.rho_m == 4.0
    assert cfg.nurbs_degree == 3 and cfg.n_samples_check == 2000
    assert cfg.search == "dijkstra" and cfg.connectivity == 8


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("resolution_m", 0.0),
        ("resolution_m", 10.0),
        ("rho0_m", -0.1),
        ("rho_m", 0.5),  # must exceed rho0_m = 1.0
        ("k_r", 0.0),
        ("smoothing_len", -1),
        ("search", "bfs"),
        ("connectivity", 4),
        ("nurbs_degree", 1),
        ("nurbs_degree", 7),
        ("refine_method", "newton"),
        ("refine_rounds", 0),
        ("n_samples_check", 10),
        ("curvature_margin", 1.5),
        ("curvature_margin", 0.0),
        ("corridor_halfwidth_m", -1.0),
        ("deviation_threshold_m", float("nan")),
        ("min_replan_interval_s", float("inf")),
        ("first_plan_wait_s", -1.0),
        ("first_plan_wait_s", float("nan")),
        ("intent_margin_m", -0.1),
        ("intent_margin_m", float("inf")),
        ("penalty_clearance", -1.0),
        ("period_s", 0.0),
    ],
)
def test_bad_values_are_rejected_naming_the_field(field: str, value: object) -> None:
    with pytest.raises(ValueError, match=f"^{field}:"):
        PlannerConfig(**{field: value})  # type: ignore[arg-type]


def test_a_sweep_sets_the_planners_tuning_and_a_bad_value_names_its_key() -> None:
    # plan-and-verify and stepping aside are tuned in one validated section, planner.tuning
    from common.config.errors import ConfigError
    from common.config.scenario import load_scenario

    s, _ = load_scenario(DEFAULT, ["planner.tuning.evade_s=5.0"])
    assert s.planner.tuning.evade_s == 5.0
    with pytest.raises(ConfigError, match=r"planner\.tuning\.rollout_slow_factor"):
        load_scenario(DEFAULT, ["planner.tuning.rollout_slow_factor=1.5"])
