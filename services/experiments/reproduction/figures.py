"""Figures like the paper's 2 to 6: trajectories against the optimal path, and time vs distance."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from common.config.world import WorldConfig
from common.world import World

if TYPE_CHECKING:
    from matplotlib.axes import Axes
    from matplotlib.figure import Figure

COLOURS = {"nurbs": "tab:green", "backstepping": "tab:blue", "fuzzy_pid": "tab:red"}
NAMES = {"nurbs": "NURBS method", "backstepping": "Backstepping", "fuzzy_pid": "immune fuzzy PID"}
CONTROL_MARK_EVERY = 10  # a marker every 10th control action keeps the paper's "control points"


def _figure(width_in: float, height_in: float) -> Figure:
    """A figure without pyplot (no global state, PNG through Agg); matplotlib is imported
    here, for its second of import is not worth paying in every process that loads this."""
    from matplotlib.figure import Figure

    return Figure(figsize=(width_in, height_in), layout="constrained")


def load_trajectory(path: Path) -> dict[str, np.ndarray]:
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def _world(ax: Axes, cfg: WorldConfig, t_end: float) -> None:
    """Static obstacles filled, moving ones as their track over the run, start and goal."""
    from matplotlib.patches import Circle, Polygon

    for c in cfg.circles:
        ax.add_patch(Circle((c.x_m, c.y_m), c.radius_m, color="0.6", zorder=1))
    for p in cfg.polygons:
        ax.add_patch(Polygon(np.asarray(p.vertices_m).reshape(-1, 2), color="0.6", zorder=1))
    world = World(cfg)
    ts = np.linspace(0.0, max(t_end, 1e-3), 200)
    for m in cfg.moving:
        xy = np.array(
            [[o.x, o.y] for t in ts for o in world.obstacles_at(float(t)) if o.id == m.id]
        )
        ax.plot(xy[:, 0], xy[:, 1], ":", color="0.4", lw=1, zorder=1)
        ax.add_patch(Circle((xy[-1, 0], xy[-1, 1]), m.radius_m, fill=False, ec="0.4", zorder=1))
    ax.plot(cfg.start.x_m, cfg.start.y_m, "ks", ms=6, zorder=4)
    ax.plot(cfg.goal.x_m, cfg.goal.y_m, "k*", ms=11, zorder=4)
    ax.set_xlim(cfg.area.x_min_m, cfg.area.x_max_m)
    ax.set_ylim(cfg.area.y_min_m, cfg.area.y_max_m)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.grid(True, alpha=0.25)


def _optimal(ax: Axes, traj: dict[str, np.ndarray]) -> None:
    if "optimal_path" in traj:
        p = traj["optimal_path"]
        ax.plot(p[:, 0], p[:, 1], "k--", lw=1.2, label="optimal path (first plan)", zorder=2)


def _trajectory(ax: Axes, ctrl: str, traj: dict[str, np.ndarray], marks: bool) -> None:
    tr = traj["truth"]
    ax.plot(
        tr[:, 1], tr[:, 2], color=COLOURS.get(ctrl), lw=1.6, label=NAMES.get(ctrl, ctrl), zorder=3
    )
    ct = traj["cmd_t"]
    if marks and len(ct) and len(tr):
        sel = ct[::CONTROL_MARK_EVERY]
        ax.plot(
            np.interp(sel, tr[:, 0], tr[:, 1]),
            np.interp(sel, tr[:, 0], tr[:, 2]),
            "x",
            color=COLOURS.get(ctrl),
            ms=4,
            label=f"control points (every {CONTROL_MARK_EVERY}th)",
            zorder=3,
        )


def trajectory_figure(
    path: Path, cfg: WorldConfig, ctrl: str, traj: dict[str, np.ndarray], title: str
) -> None:
    """Figures 2-4: one controller's trajectory and control points against the optimal path."""
    fig = _figure(10.0, 4.8)
    ax = fig.add_subplot()
    t_end = float(traj["truth"][-1, 0]) if len(traj["truth"]) else 0.0
    _world(ax, cfg, t_end)
    _optimal(ax, traj)
    _trajectory(ax, ctrl, traj, marks=True)
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize="small")
    fig.savefig(path, dpi=110)


def overlay_figure(
    path: Path, cfg: WorldConfig, trajs: dict[str, dict[str, np.ndarray]], title: str
) -> None:
    """Figure 5: the three trajectories overlaid on the optimal path."""
    fig = _figure(10.0, 4.8)
    ax = fig.add_subplot()
    t_end = max((float(t["truth"][-1, 0]) for t in trajs.values() if len(t["truth"])), default=0.0)
    _world(ax, cfg, t_end)
    first = next(iter(trajs.values()), None)
    if first is not None:
        _optimal(ax, first)
    for ctrl, traj in trajs.items():
        _trajectory(ax, ctrl, traj, marks=False)
    ax.set_title(title)
    ax.legend(loc="upper left", fontsize="small")
    fig.savefig(path, dpi=110)


def distance_travelled(truth: np.ndarray) -> np.ndarray:
    """Cumulative path length along the true trajectory (m), one value per row."""
    if len(truth) == 0:
        return np.zeros(0)
    step = np.hypot(np.diff(truth[:, 1]), np.diff(truth[:, 2]))
    return np.concatenate([[0.0], np.cumsum(step)])


def time_distance_figure(path: Path, trajs: dict[str, dict[str, np.ndarray]], title: str) -> None:
    """Figure 6: time against distance travelled (the slope is 1 / speed, eq. 21)."""
    fig = _figure(7.0, 4.5)
    ax = fig.add_subplot()
    for ctrl, traj in trajs.items():
        tr = traj["truth"]
        if len(tr):
            ax.plot(
                distance_travelled(tr),
                tr[:, 0] - tr[0, 0],
                color=COLOURS.get(ctrl),
                label=NAMES.get(ctrl, ctrl),
            )
    ax.set_xlabel("distance travelled (m)")
    ax.set_ylabel("time (s)")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small")
    fig.savefig(path, dpi=110)
