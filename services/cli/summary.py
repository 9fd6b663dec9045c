"""What `tidelink run` and `tidelink launch` print at a run's end: a short verdict (outcome,
min clearance, travel time, cross-track and estimation RMS) and where the outputs are; every
scalar metric only with --verbose (metrics.json has them all, docs/metrics.md says what each
is).

The verdict reads the AUV mission's keys; a fleet's per-vehicle ones (cross-track, estimate)
are given as the worst vehicle's. A mission that has none of them (the runtime self-test
loop) gets the full table instead: the verdict would be empty.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

VerdictRow = tuple[str, str]  # (label, value in words)


def print_summary(
    metrics: dict[str, Any], outputs: list[tuple[str, Path]], *, all_metrics: bool
) -> None:
    """The verdict (or, with `all_metrics` or a mission without the verdict's keys, every
    scalar metric first), then one `what: where` line per output."""
    rows = verdict_rows(metrics)
    if all_metrics or not rows:
        print_metrics_table(metrics)
    if rows:
        width = max(len(label) for label, _ in rows)
        for label, value in rows:
            print(f"  {label:<{width}}  {value}")
    for what, where in outputs:
        hint = (
            " (every metric: --verbose)" if what == "metrics" and rows and not all_metrics else ""
        )
        print(f"{what}: {where}{hint}")


def print_metrics_table(metrics: dict[str, Any]) -> None:
    """The scalar metrics, one per line, sorted by name."""
    width = max((len(k) for k in metrics), default=0)
    for k, v in sorted(metrics.items()):
        if isinstance(v, dict | list):
            continue
        if isinstance(v, float):
            v = f"{v:.4g}" if math.isfinite(v) else str(v)
        print(f"  {k:<{width}}  {v}")


def verdict_rows(m: dict[str, Any]) -> list[VerdictRow]:
    """The verdict's lines of a run's metrics; [] when none of its keys is there."""
    rows = (
        _outcome(m),
        _clearance(m),
        _travel(m),
        _worst(m, "cross-track RMS", "xte_planned", "to the path in force"),
        _worst(m, "estimation RMS", "estimation", "of the position estimate"),
    )
    return [row for row in rows if row is not None]


def _outcome(m: dict[str, Any]) -> VerdictRow | None:
    from services.mission.outcome import outcome_of

    outcome = outcome_of(m)
    if outcome is None:
        return None
    if m.get("end_reason") == "interrupted":
        return "outcome", "none: the run was interrupted"
    end = "" if outcome == "success" else f" (the run ended on {m.get('end_reason')})"
    return "outcome", f"{outcome}{end}"


def _clearance(m: dict[str, Any]) -> VerdictRow | None:
    if "min_clearance_m" not in m:
        return None
    v = _num(m.get("min_clearance_m"))
    if not math.isfinite(v):
        value = "none measured (no obstacle in this world)"
    else:
        t = _num(m.get("min_clearance_t_s"))
        when = f" at t = {t:.2f} s" if math.isfinite(t) else ""
        rho0 = m.get("rho0_m")
        value = f"{v:.2f} m{when}" + ("" if rho0 is None else f" (rho0 = {float(rho0)} m)")
    sep = _num(m.get("min_separation_m"))
    if math.isfinite(sep):  # a fleet: the nearest two hulls came, too
        pair = str(m.get("min_separation_pair") or "").replace("-", " and ")
        value += f"; hull to hull {sep:.2f} m" + (f" ({pair})" if pair else "")
    return "min clearance", value


def _travel(m: dict[str, Any]) -> VerdictRow | None:
    if "reached_goal" not in m:
        return None
    if not m["reached_goal"]:
        short = _num(m.get("final_distance_to_goal_m"))
        where = f", {short:.1f} m short" if math.isfinite(short) else ""
        if "vehicles_reached" in m:
            where = f", {m['vehicles_reached']} of {m.get('fleet_size', '?')} vehicles there"
        return "travel time", f"goal not reached (t = {_num(m.get('t_end_s')):.2f} s{where})"
    travel = _num(m.get("travel_time_s"))
    length, speed = _num(m.get("path_length_m")), _num(m.get("mean_speed_mps"))
    how = f" ({length:.1f} m at {speed:.2f} m/s)" if math.isfinite(length * speed) else ""
    if "fleet_size" in m:
        how = " (the last vehicle's arrival)"
    return "travel time", f"{travel:.2f} s{how}"


def _worst(m: dict[str, Any], label: str, error: str, of: str) -> VerdictRow | None:
    """An error's RMS and max (keys `error`_rms_m, `error`_max_m), or in a fleet the worst
    vehicle's."""
    rms, peak = f"{error}_rms_m", f"{error}_max_m"
    vehicles: dict[str, dict[str, Any]] = m.get("vehicles") or {}
    if rms in m:
        owner, source = "", m
    elif vehicles and any(rms in v for v in vehicles.values()):

        def error_of(vid: str) -> float:
            return _num(vehicles[vid].get(rms), -math.inf)

        worst = max(vehicles, key=error_of)
        owner, source = f"; {worst}, the worst of {len(vehicles)}", vehicles[worst]
    else:
        return None
    v = _num(source.get(rms))
    if not math.isfinite(v):
        return label, "not measured"
    most = _num(source.get(peak))
    top = f"max {most:.3g} m" if math.isfinite(most) else ""
    return label, f"{v:.3g} m {of} ({top}{owner})"


def _num(v: Any, default: float = math.nan) -> float:
    """A metric as a float; `default` for a missing or null one (a run cut short)."""
    if v is None or isinstance(v, bool) or not isinstance(v, int | float):
        return default
    return float(v)
