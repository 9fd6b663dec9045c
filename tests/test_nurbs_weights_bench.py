"""Smoke test of scripts/bench_nurbs_weights.py (the experiment behind fit.py's fixed weights)."""

from __future__ import annotations

import math

import pytest

from tests.helpers.scripts import load_script


def test_the_weights_experiment_compares_points_only_with_points_and_weights(
    capsys: pytest.CaptureFixture[str],
) -> None:
    bench = load_script("bench_nurbs_weights")
    (row,) = bench.main(n_varied=0, n_fields=0, max_iter=3)  # the default plan only
    assert row.plan.ok and all(math.isfinite(v.f) for v in (row.plan, row.points, row.joint))
    # more refinement never makes F worse than the plan's, and the weights stay in bounds
    assert row.points.f <= row.plan.f and row.joint.f <= row.plan.f + 1e-9
    assert 0.2 - 1e-9 <= row.w_range[0] <= row.w_range[1] <= 5.0 + 1e-9
    assert "gain in F" in capsys.readouterr().out
