"""Sweep plots: each metric against the swept parameter, one line per other cell, 95 % bands."""

from __future__ import annotations

import math
from pathlib import Path

from services.experiments.sweep.schema import Axis
from services.experiments.sweep.stats import Estimate
from services.experiments.sweep.summary import CellStats

# what is worth a figure (the others are in summary.csv)
PLOT_METRICS = {
    "success": "success rate (goal, no contact, never inside rho0)",
    "travel_time_s": "travel time, eq. (21) (s)",
    "xte_optimal_rms_m": "cross-track error to the optimal path, RMS (m)",
    "xte_optimal_max_m": "cross-track error to the optimal path, max (m)",
    "min_clearance_m": "minimum clearance, eq. (12) (m)",
    "control_actions_on_path": "control actions on the optimal path",
    "on_path_fraction": "share of control actions on the optimal path",
    "path_length_m": "executed path length (m)",
    "commands_rejected_stale": "commands rejected as stale",
    "hold_time_s": "time in HOLD (s)",
    "failsafe_time_s": "time in FAILSAFE (s)",
    "net_delivery_ratio": "messages delivered / sent, every link",
    "net_dropped_queue": "messages dropped by a full queue (modem), every link",
    # fleets (services/mission/fleet_metrics.py)
    "min_separation_m": "minimum hull-to-hull separation between vehicles (m)",
    "vehicle_collisions": "vehicle-vehicle contacts",
    "vehicles_reached": "vehicles at their goals",
    "intent_fraction": "share of planner steps by another vehicle's intent (not its track)",
}


def _estimate(c: CellStats, metric: str) -> Estimate | None:
    return c.success if metric == "success" else c.metrics.get(metric)


def plot_sweep(
    out: Path,
    cells: list[CellStats],
    axis: Axis,
    grid: tuple[str, ...],
    title: str,
    *,
    metrics: dict[str, str] | None = None,
    folder: str = "plots",
    dash_axis: str = "",
) -> list[Path]:
    """One PNG per metric (PLOT_METRICS unless given: name -> y label) in out/<folder>/;
    returns the files written. With dash_axis, a line whose value on that axis is not the
    first one seen is dashed, in the colour of the line it differs from only there."""
    plots = out / folder
    plots.mkdir(parents=True, exist_ok=True)
    order = [v.label for v in axis.values]
    xs = {v.label: (v.x if axis.numeric else float(i)) for i, v in enumerate(axis.values)}
    others = tuple(g for g in grid if g != axis.name)
    lines: dict[str, list[CellStats]] = {}
    for c in cells:
        name = ", ".join(c.labels[g] for g in others) or "all"
        lines.setdefault(name, []).append(c)
    styles = _styles(lines, others, dash_axis) if dash_axis in others else {}
    # no pyplot: no global state, PNG through Agg; imported here, for a second of import is
    # not worth paying in every process that only reads a sweep
    from matplotlib.figure import Figure

    written = []
    for metric, ylabel in (PLOT_METRICS if metrics is None else metrics).items():
        if not any(_estimate(c, metric) is not None for c in cells):
            continue
        fig = Figure(figsize=(7.0, 4.2), layout="constrained")
        ax = fig.add_subplot()
        for name, cs in lines.items():
            pts = sorted(
                (
                    (xs[c.labels[axis.name]], _estimate(c, metric))
                    for c in cs
                    if c.labels[axis.name] in xs
                ),
                key=lambda p: p[0],
            )
            pts2 = [(x, e) for x, e in pts if e is not None and math.isfinite(e.mean)]
            if not pts2:
                continue
            x = [p[0] for p in pts2]
            colour, dash = styles.get(name, (None, "-"))
            (ln,) = ax.plot(
                x, [e.mean for _, e in pts2], marker="o", label=name, color=colour, linestyle=dash
            )
            band = [(xx, e.low, e.high) for xx, e in pts2 if math.isfinite(e.low)]
            if band:
                ax.fill_between(
                    [b[0] for b in band],
                    [b[1] for b in band],
                    [b[2] for b in band],
                    color=ln.get_color(),
                    alpha=0.18,
                    linewidth=0,
                )
        if not axis.numeric:
            ax.set_xticks([xs[lab] for lab in order], order)
        ax.set_xlabel(axis.x_label or axis.name)
        ax.set_ylabel(ylabel)
        ax.set_title(f"{title}: {metric}")
        ax.grid(True, alpha=0.3)
        if len(lines) > 1 and ax.get_legend_handles_labels()[0]:
            ax.legend(title=", ".join(others) or None, fontsize="small")
        path = plots / f"{metric}.png"
        fig.savefig(path, dpi=110)
        written.append(path)
    return written


def _styles(
    lines: dict[str, list[CellStats]], others: tuple[str, ...], dash_axis: str
) -> dict[str, tuple[str, str]]:
    """Line name -> (colour, line style): a colour per value of the other axes, dashed for
    every value of dash_axis but the first seen."""
    palette = [f"C{i}" for i in range(10)]
    colours: dict[tuple[str, ...], str] = {}
    first = ""
    out = {}
    for name, cs in lines.items():
        labels = cs[0].labels
        key = tuple(labels[g] for g in others if g != dash_axis)
        colour = colours.setdefault(key, palette[len(colours) % len(palette)])
        first = first or labels[dash_axis]
        out[name] = (colour, "-" if labels[dash_axis] == first else "--")
    return out
