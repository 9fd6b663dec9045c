"""What a finished run leaves on disk (metrics.json, run.png), and what it could not write."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

from common.config.scenario import Scenario
from common.runtime.metrics_record import RunMetrics
from common.runtime.model.result import RunResult
from common.runtime.run import OutputsNotWritten, write_outputs

if TYPE_CHECKING:
    from services.launcher.plot_worker import PlotWorker


@dataclass
class SavedRun:
    """The run's metrics (written or not), its plot if drawn, and what could not be written."""

    metrics: RunMetrics[msgspec.Struct]
    plot: Path | None = None
    unwritten: list[str] = field(default_factory=list)  # a full disk (say) kept these out


def save_run(
    result: RunResult,
    scenario: Scenario,
    out: Path,
    *,
    wall_s: float,
    plot: bool,
    worker: PlotWorker | None = None,
) -> SavedRun:
    """Write out/metrics.json and (with `plot`) out/run.png, drawn by `worker` if given (it
    imported matplotlib while the mission ran), else here; a write that fails is told in
    `unwritten`, never raised: the run's outcome is still the caller's to report."""
    try:
        saved = SavedRun(write_outputs(result, scenario, out, wall_s=wall_s))
    except OutputsNotWritten as exc:
        saved = SavedRun(exc.metrics, unwritten=[str(exc)])
    if plot:
        from services.launcher.plot import plot_result, result_sketch

        png = out / "run.png"
        try:
            if worker is None:
                saved.plot = plot_result(result, scenario, png)
            else:
                saved.plot = worker.draw(result_sketch(result, scenario).calls, png)
        except OSError as exc:
            saved.unwritten.append(f"could not write {png}: {exc}")
    return saved
