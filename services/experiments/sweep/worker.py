"""Execute one run of a sweep anywhere (this process, a pool worker, a Dask worker).

The function takes and returns plain picklable data and never writes into the sweep folder,
so it runs the same on another machine; the caller records the outcome.
"""

from __future__ import annotations

import logging
import math
import tempfile
import time
import traceback
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import msgspec
import numpy as np

from common.config.scenario import scenario_from_raw
from common.runtime.metrics_record import Row, RunMetrics
from common.runtime.model.inproc import RunResult
from common.runtime.run import run_scenario, write_outputs
from services.experiments.sweep.grid import RunSpec
from services.mission.records import AuvMetrics, auv_metrics

log = logging.getLogger("tidelink.sweep")


@dataclass(frozen=True, kw_only=True)
class RunOutcome:
    """What one run produced: status, metrics (as metrics.json has them), optional trajectory."""

    run_id: str
    status: str  # "ok" or "error"
    error: str = ""  # the exception, with its traceback, when status == "error"
    metrics: RunMetrics[msgspec.Struct] | None = None  # None: an error
    wall_s: float = 0.0
    trajectory: dict[str, np.ndarray] = field(default_factory=dict)


def execute_run(spec: RunSpec) -> RunOutcome:
    """Run one scenario to its end; any failure becomes an 'error' outcome, never an exception."""
    t0 = time.monotonic()
    try:
        scenario = scenario_from_raw(spec.raw)
        with tempfile.TemporaryDirectory(prefix="tidelink-sweep-") as tmp:
            log_dir = _log_dir(spec, Path(tmp))
            result = run_scenario(scenario, spec.raw, log_dir=log_dir)
            # write_outputs adds the run facts and link statistics exactly as `tidelink run`
            metrics = write_outputs(
                result, scenario, Path(tmp) / "out", wall_s=time.monotonic() - t0
            )
        traj = trajectory_of(result) if spec.keep_trajectory else {}
        return RunOutcome(
            run_id=spec.run_id,
            status="ok",
            metrics=metrics,
            wall_s=time.monotonic() - t0,
            trajectory=traj,
        )
    except Exception as exc:  # noqa: BLE001 - a failed run is a result, recorded with its error
        log.warning("run %s failed: %s", spec.run_id, exc)
        return RunOutcome(
            run_id=spec.run_id,
            status="error",
            error=f"{type(exc).__name__}: {exc}\n{traceback.format_exc()}",
            wall_s=time.monotonic() - t0,
        )


def _log_dir(spec: RunSpec, tmp: Path) -> Path:
    """The requested log folder if this machine can create it, else a temporary one."""
    if spec.log_dir:
        try:
            Path(spec.log_dir).mkdir(parents=True, exist_ok=True)
            return Path(spec.log_dir)
        except OSError:
            pass
    return tmp / "logs"


def trajectory_of(result: RunResult) -> dict[str, np.ndarray]:
    """Truth rows (t, x, y, theta, v, w), command stamps, and the first planned path (points)."""
    from common.messages import PathMsg, TruthState, VelocityCommand

    rec = result.record
    truth = [m for m in rec.stream("vehicle", "truth") if isinstance(m, TruthState)]
    # the commander: the planner, or the onboard tracker (controller.placement)
    source = "tracker" if ("tracker", "cmd") in rec.keys() else "planner"
    cmds = [m for m in rec.stream(source, "cmd") if isinstance(m, VelocityCommand)]
    paths = [
        m for m in rec.stream("planner", "path") if isinstance(m, PathMsg) and m.status == "OK"
    ]
    out = {
        "truth": np.array(
            [(q.stamp, q.x, q.y, q.theta, q.v, q.w) for q in truth], dtype=np.float64
        ).reshape(-1, 6),
        "cmd_t": np.array([c.stamp for c in cmds], dtype=np.float64),
    }
    if paths:
        # the mission's own path sampler, so the figures show the path its metrics measure
        from services.mission.metrics import path_points

        p = paths[0]  # the "optimal path" of the metrics: planned at the start
        out["optimal_path"] = path_points(p, n=2000)
        out["optimal_waypoints"] = np.asarray(p.waypoints, dtype=np.float64).reshape(-1, 2)
    return out


def row_of(spec: RunSpec, outcome: RunOutcome, runtime: str, finished_at: str) -> Row:
    """The results.csv row of a run: ids, grid parameters, status, then every scalar metric."""
    row: Row = {"run_id": spec.run_id, "status": outcome.status, "seed": spec.seed}
    row.update(spec.labels)
    row.update(
        {
            "runtime": runtime,
            "wall_s": round(outcome.wall_s, 3),
            "finished_at": finished_at,
            "error": outcome.error.strip().splitlines()[0] if outcome.error else "",
        }
    )
    m = outcome.metrics
    if m is None:
        return row
    mission = auv_metrics(m)
    # paper §4 success: reached the goal without touching an obstacle, and never inside the
    # safety distance rho0 (the AUV mission's judgment, services/mission/outcome.py); its
    # `outcome` column says which failure otherwise. A run that failed is still data
    # (status "ok"); a mission that does not judge runs never succeeds
    row["success"] = mission is not None and mission.success
    if isinstance(mission, AuvMetrics):
        acts, on = mission.control_actions, mission.control_actions_on_path
        if isinstance(acts, int) and isinstance(on, int) and acts > 0:
            row["on_path_fraction"] = on / acts
    row.update(_link_totals(m.facts.link_stats))
    row.update({k: v for k, v in m.to_row().items() if k not in row})
    return row


def _link_totals(stats: Mapping[str, Mapping[str, int | float | None]]) -> dict[str, int | float]:
    """Network totals over every link (the per-link numbers are in the run's metrics.json)."""
    keys = ("sent", "delivered", "dropped_loss", "dropped_outage", "dropped_queue")
    tot: dict[str, int | float] = {
        f"net_{k}": sum(int(s.get(k) or 0) for s in stats.values()) for k in keys
    }
    sent = tot["net_sent"]
    tot["net_delivery_ratio"] = tot["net_delivered"] / sent if sent else math.nan
    return tot
