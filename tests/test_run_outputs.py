"""A run whose outputs cannot be written still hands back its metrics and says what is missing
(services/launcher/outputs.py: `tidelink run` and `tidelink launch` alike)."""

from __future__ import annotations

from pathlib import Path

from common.config.scenario import load_scenario
from common.runtime.model.inproc import run_inproc
from services.launcher.outputs import save_run

SMALL = Path(__file__).resolve().parents[1] / "configs" / "experiments" / "scenarios" / "small.toml"


def test_a_run_that_cannot_write_its_outputs_keeps_its_metrics_and_says_what_is_missing(
    tmp_path: Path,
) -> None:
    s, _ = load_scenario(SMALL, ["run.max_time_s=3.0"])
    result = run_inproc(s)
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")  # out/ cannot be made: as a full disk, every write fails
    saved = save_run(result, s, blocked, wall_s=1.0, plot=True)
    written = saved.metrics.to_json()
    assert written["outcome"] == result.metrics.outcome and "t_end_s" in written
    assert saved.plot is None
    metrics_why, plot_why = saved.unwritten
    assert f"could not write {blocked / 'metrics.json'}" in metrics_why
    assert f"could not write {blocked / 'run.png'}" in plot_why
    ok = save_run(result, s, tmp_path / "out", wall_s=1.0, plot=False)
    assert ok.unwritten == [] and (tmp_path / "out" / "metrics.json").exists()
