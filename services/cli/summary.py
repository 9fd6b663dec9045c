"""What `tidelink run` and `tidelink launch` print at a run's end: a short verdict (outcome,
min clearance, travel time, cross-track and estimation RMS) and where the outputs are; every
scalar metric only with --verbose (metrics.json has them all, docs/metrics.md says what each
is).

The verdict reads the AUV mission's record; a fleet's per-vehicle ones (cross-track, estimate)
are given as the worst vehicle's. A mission that is not the AUV's (the runtime self-test
loop) gets the full table instead: the verdict would be empty.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any, Protocol

from msgspec import UnsetType

from common.runtime.metrics_record import RunFacts, RunMetrics
from services.mission.records import AuvMetrics, FleetMetrics, MissionMetrics, auv_metrics

VerdictRow = tuple[str, str]  # (label, value in words)
# one vehicle's error metric (m): its RMS and max; None or UNSET when not measured
Error = Callable[[AuvMetrics], tuple[object, object]]


def print_summary(
    metrics: RunMetrics[Any], outputs: list[tuple[str, Path]], *, all_metrics: bool
) -> None:
    """The verdict (or, with `all_metrics` or a mission without the verdict's keys, every
    scalar metric first), then one `what: where` line per output."""
    rows = verdict_rows(metrics)
    if all_metrics or not rows:
        print_metrics_table(metrics.to_json())
    if rows:
        width = max(len(label) for label, _ in rows)
        for label, value in rows:
            print(f"  {label:<{width}}  {value}")
    for what, where in outputs:
        hint = (
            " (every metric: --verbose)" if what == "metrics" and rows and not all_metrics else ""
        )
        print(f"{what}: {where}{hint}")


class Saved(Protocol):
    """What a run left in its folder: its metrics (written or not), its plot if drawn, and
    the outputs that could not be written (services/launcher/outputs.py SavedRun, a launch's
    LaunchOutcome)."""

    @property
    def metrics(self) -> RunMetrics[Any]: ...

    @property
    def plot(self) -> Path | None: ...

    @property
    def unwritten(self) -> list[str]: ...


def print_run_end(
    saved: Saved,
    out: Path,
    *,
    json_output: bool,
    all_metrics: bool,
    more: Sequence[tuple[str, Path]] = (),
    notes: Sequence[str] = (),
) -> None:
    """What a command that ran a mission into folder `out` prints at its end: the metrics as
    one JSON object (`json_output`), or the summary and where the outputs are (metrics.json
    unless it could not be written, the plot if drawn, then `more`); then each of `notes`
    (on stderr beside JSON) and each output that could not be written, on stderr."""
    if json_output:
        print(json.dumps(saved.metrics.to_json(), sort_keys=True, allow_nan=False))
    else:
        written = not any("metrics.json" in w for w in saved.unwritten)
        outputs = [("metrics", out / "metrics.json")] if written else []
        outputs += [("plot", saved.plot)] if saved.plot is not None else []
        print_summary(saved.metrics, [*outputs, *more], all_metrics=all_metrics)
        if not written:
            print("metrics: not written (see below)")
    for line in notes:
        print(line, file=sys.stderr if json_output else sys.stdout)
    for why in saved.unwritten:  # the outcome is still the run's: reported below, as ever
        print(f"tidelink: error: {why}", file=sys.stderr)


def print_metrics_table(metrics: dict[str, object]) -> None:
    """The scalar metrics of a metrics.json object, one per line, sorted by name."""
    width = max((len(k) for k in metrics), default=0)
    for k, v in sorted(metrics.items()):
        if isinstance(v, dict | list):
            continue
        if isinstance(v, float):
            v = f"{v:.4g}" if math.isfinite(v) else str(v)
        print(f"  {k:<{width}}  {v}")


def verdict_rows(metrics: RunMetrics[Any]) -> list[VerdictRow]:
    """The verdict's lines of a run's metrics; [] for a mission other than the AUV's."""
    m = auv_metrics(metrics)
    if m is None:
        return []
    return [
        _outcome(m, metrics.facts),
        *_clearance(m),
        _travel(m, metrics.facts),
        *_worst(m, "cross-track RMS", _xte, "to the path in force"),
        *_worst(m, "estimation RMS", _estimation, "of the position estimate"),
    ]


def _xte(v: AuvMetrics) -> tuple[object, object]:
    return v.xte_planned_rms_m, v.xte_planned_max_m


def _estimation(v: AuvMetrics) -> tuple[object, object]:
    return v.estimation_rms_m, v.estimation_max_m


def _outcome(m: MissionMetrics, facts: RunFacts) -> VerdictRow:
    if facts.end_reason == "interrupted":
        return "outcome", "none: the run was interrupted"
    end = "" if m.outcome == "success" else f" (the run ended on {facts.end_reason})"
    return "outcome", f"{m.outcome}{end}"


def _clearance(m: MissionMetrics) -> list[VerdictRow]:
    """[] for a run without a truth state (nothing to measure a clearance of)."""
    if not _given(m.min_clearance_m):
        return []
    v = _num(m.min_clearance_m)
    if not math.isfinite(v):
        value = "none measured (no obstacle in this world)"
    else:
        t = _num(m.min_clearance_t_s) if isinstance(m, AuvMetrics) else math.nan
        when = f" at t = {t:.2f} s" if math.isfinite(t) else ""
        rho0 = f" (rho0 = {m.rho0_m} m)" if isinstance(m.rho0_m, float) else ""
        value = f"{v:.2f} m{when}{rho0}"
    if isinstance(m, FleetMetrics) and math.isfinite(sep := _num(m.min_separation_m)):
        pair = m.min_separation_pair.replace("-", " and ")  # the nearest two hulls came
        value += f"; hull to hull {sep:.2f} m" + (f" ({pair})" if pair else "")
    return [("min clearance", value)]


def _travel(m: MissionMetrics, facts: RunFacts) -> VerdictRow:
    if not m.reached_goal:
        if isinstance(m, FleetMetrics):
            where = f", {m.vehicles_reached} of {m.fleet_size} vehicles there"
        else:
            short = _num(m.final_distance_to_goal_m)
            where = f", {short:.1f} m short" if math.isfinite(short) else ""
        return "travel time", f"goal not reached (t = {_num(facts.t_end_s):.2f} s{where})"
    travel = _num(m.travel_time_s)
    if isinstance(m, FleetMetrics):
        return "travel time", f"{travel:.2f} s (the last vehicle's arrival)"
    length, speed = _num(m.path_length_m), _num(m.mean_speed_mps)
    how = f" ({length:.1f} m at {speed:.2f} m/s)" if math.isfinite(length * speed) else ""
    return "travel time", f"{travel:.2f} s{how}"


def _worst(m: MissionMetrics, label: str, error: Error, of: str) -> list[VerdictRow]:
    """An error's RMS and max, or in a fleet the worst vehicle's; [] when no vehicle has it."""
    if isinstance(m, AuvMetrics):
        owner, source = "", m
    elif m.vehicles and any(_given(error(v)[0]) for v in m.vehicles.values()):
        worst = max(m.vehicles, key=lambda vid: _num(error(m.vehicles[vid])[0], -math.inf))
        owner, source = f"; {worst}, the worst of {len(m.vehicles)}", m.vehicles[worst]
    else:
        return []
    rms, peak = error(source)
    if not _given(rms):
        return []
    v = _num(rms)
    if not math.isfinite(v):
        return [(label, "not measured")]
    most = _num(peak)
    top = f"max {most:.3g} m" if math.isfinite(most) else ""
    return [(label, f"{v:.3g} m {of} ({top}{owner})")]


def _given(v: object) -> bool:
    """Is the metric in the file at all (null included: measured as nothing)?"""
    return not isinstance(v, UnsetType)


def _num(v: object, default: float = math.nan) -> float:
    """A metric as a float; `default` for a missing or null one (a run cut short)."""
    if v is None or isinstance(v, bool) or not isinstance(v, int | float):
        return default
    return float(v)
