"""The planner's response model against the REMUS hull it predicts (scripts/identify_response.py).

configs/ocean.toml keeps the unicycle's lags (note 0061): the test measures how far they put
the model from the hull, and checks that the identified ones bring it close.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.scenario import load_scenario
from tests.helpers.scripts import load_script

CONFIGS = Path(__file__).resolve().parents[1] / "configs"
tool = load_script("identify_response")


def test_identified_lags_follow_the_hull_the_unicycle_lags_do_not() -> None:
    """Identified: within 2 deg of the hull's heading through turns begun, ended and reversed,
    and 0.6 m of its run through speed steps; the unicycle's lags: 10 deg and 2 m off."""
    vehicle = load_scenario(CONFIGS / "ocean.toml")[0].vehicle
    trials = tool.plant_trials(vehicle)
    fitted = tool.identify(vehicle, trials)
    assert (fitted.yaw_tau_s, fitted.yaw_accel_max_rps2, fitted.accel_max_mps2) == (
        0.4,
        0.2,
        0.2,
    )
    ours, theirs = tool.mismatch(fitted, trials), tool.mismatch(vehicle, trials)
    assert ours.heading_rad < 0.035
    assert ours.along_m < 0.6
    assert theirs.heading_rad > 0.15
    assert theirs.along_m > 2.0


def test_the_tool_prints_both(capsys: pytest.CaptureFixture[str]) -> None:
    tool.main([str(CONFIGS / "ocean.toml")])
    out = capsys.readouterr().out
    assert "configured: yaw_tau_s = 0.5" in out
    assert "identified: yaw_tau_s = 0.4, yaw_accel_max_rps2 = 0.2, accel_max_mps2 = 0.2" in out


def test_unicycle_plant_has_nothing_to_identify() -> None:
    with pytest.raises(SystemExit, match="nothing to identify"):
        tool.main([str(CONFIGS / "default.toml")])
