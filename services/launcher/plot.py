"""A PNG plot of a run: true trajectory, estimate, the planned NURBS paths (bold: the part of
each that was in force as the vehicle flew it; faint: each whole, as planned; each replan
marked with its reason), obstacles and their tracks, start and goal; a fleet's tracks dotted
in time, with its closest approach marked; the ocean current, if any, as light arrows at
mid-run. Worked out without matplotlib into a Sketch (sketch.py), which draws it."""

from __future__ import annotations

import re
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from common.config.scenario import Scenario
from common.messages import Message, ObstacleTracks, PathMsg, StateEstimate, TruthState
from common.runtime.model.dataflow import vehicle_of
from common.runtime.model.record import Record
from common.runtime.model.result import RunResult
from common.world import World
from common.world.current import CurrentField
from services.launcher.sketch import Sketch, draw_sketch, save_figure, shape
from services.mission.fleet_metrics import closest_approach, fleet_truths
from services.mission.metrics import distinct_paths, path_points

if TYPE_CHECKING:  # matplotlib is imported when a figure is drawn, not with this module
    from matplotlib.figure import Figure

PATH_SAMPLES = 400  # points per planned path: smooth at this figure size
TIME_MARK_S = 10.0  # a fleet's tracks are dotted this often (mission s)
CURRENT_COLUMNS = 20  # the current's arrows: this many across the area, rows to keep them square
LABEL_MERGE_M = 8.0  # replans of one reason this close together share a label ("current x4")


# one colour per vehicle of a fleet (matplotlib's qualitative palette)
FLEET_COLOURS = tuple(f"tab:{c}" for c in ("blue", "red", "green", "orange", "cyan", "brown"))


def _of_type(record: Record, cls: type[Message], vehicle: str | None = None) -> list[Any]:
    """Every recorded message of one type, whichever service published it (of one fleet
    vehicle's services when `vehicle` is given; "" is the single vehicle's), by stamp."""
    out = [
        m
        for key in record.keys()
        if (vehicle is None or vehicle_of(key[0]) == vehicle)
        # a fleet vehicle's "hull" repeats some of its truth states, for the others' sonars
        and not (cls is TruthState and key[1] != "truth")
        for m in record.stream(*key)
        if isinstance(m, cls)
    ]
    return sorted(out, key=lambda m: m.stamp)


def plot_result(result: RunResult, scenario: Scenario, path: Path) -> Path:
    """Draw the run's figure (result_sketch's) into `path` (PNG) and return it."""
    return save_figure(draw_sketch(result_sketch(result, scenario).calls), path)


def result_sketch(result: RunResult, scenario: Scenario) -> Sketch:
    """run_sketch with the title every command gives a run's plot: its name, seed,
    controller, runtime, how it ended and when."""
    return run_sketch(
        result.record,
        scenario,
        title=f"{scenario.run.name} (seed {scenario.run.seed}, {scenario.controller.kind}, "
        f"{scenario.runtime.kind}): {result.reason} at t={result.t_end:.1f} s",
    )


def run_figure(record: Record, scenario: Scenario, *, title: str = "") -> Figure:
    """The run's figure (as the module docstring says), not yet saved."""
    return draw_sketch(run_sketch(record, scenario, title=title).calls)


def run_sketch(record: Record, scenario: Scenario, *, title: str = "") -> Sketch:
    """The run's figure as a sketch: what it shows, worked out; matplotlib not imported."""
    w = scenario.world
    ax = Sketch()
    a = w.area
    ax.add_patch(
        shape(
            "Rectangle",
            (a.x_min_m, a.y_min_m),
            a.x_max_m - a.x_min_m,
            a.y_max_m - a.y_min_m,
            fill=False,
            ec="0.6",
            lw=0.8,
        )
    )
    # static obstacles from the chart (exact shapes), moving ones along their true motion
    for c in w.circles:
        ax.add_patch(shape("Circle", (c.x_m, c.y_m), c.radius_m, fc="0.75", ec="0.35"))
    for p in w.polygons:
        ax.add_patch(
            shape(
                "Polygon",
                np.asarray(p.vertices_m).reshape(-1, 2),
                closed=True,
                fc="0.75",
                ec="0.35",
            )
        )
    truth: list[TruthState] = _of_type(record, TruthState)
    t_end = max((q.stamp for q in truth), default=scenario.run.max_time_s)
    _draw_current(ax, scenario, 0.5 * t_end)
    world = World(w)
    times = np.linspace(0.0, t_end, 200)
    moving: dict[int, list[tuple[float, float]]] = {}
    for t in times:
        for o in world.obstacles_at(float(t)):
            if o.moving:
                moving.setdefault(o.id, []).append((o.x, o.y))
    radius = {m.id: m.radius_m for m in w.moving}
    for i, (oid, pts) in enumerate(sorted(moving.items())):
        xy = np.asarray(pts)
        ax.plot(
            xy[:, 0],
            xy[:, 1],
            ":",
            color="tab:purple",
            lw=1,
            label="moving obstacles (truth)" if i == 0 else None,
        )
        ax.add_patch(
            shape("Circle", tuple(xy[-1]), radius[oid], fc="none", ec="tab:purple", ls="--")
        )
    tracks: list[ObstacleTracks] = _of_type(record, ObstacleTracks)
    # arrays, not lists: scatter checks a list's every element for a mask (~25 ms here)
    tx = np.array([k.x for m in tracks for k in m.tracks])
    ty = np.array([k.y for m in tracks for k in m.tracks])
    if len(tx):
        ax.scatter(tx, ty, s=2, color="tab:pink", alpha=0.5, label="obstacle tracks (estimator)")
    if scenario.members:
        for k, (vid, member) in enumerate(scenario.members):
            _draw_vehicle(ax, record, member, vid, FLEET_COLOURS[k % len(FLEET_COLOURS)])
        _draw_fleet_timing(ax, record, scenario)
    else:
        _draw_vehicle(ax, record, scenario, "", "")
    ax.set_aspect("equal")
    ax.set_xlim(a.x_min_m - 2, a.x_max_m + 2)
    ax.set_ylim(a.y_min_m - 2, a.y_max_m + 2)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(
        title
        or f"run {scenario.run.name}, seed {scenario.run.seed}, "
        f"controller {scenario.controller.kind}"
    )
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.12), ncol=4, fontsize=8, frameon=False)
    return ax


def _draw_current(ax: Any, scenario: Scenario, t: float) -> None:
    """The ocean current at time t as light arrows on a coarse grid over the area, the longest
    as long as the grid's spacing; nothing in still water."""
    w = scenario.world
    water = CurrentField(w.current, w.area, scenario.run.seed)
    if water.is_calm:
        return
    a = w.area
    width, height = a.x_max_m - a.x_min_m, a.y_max_m - a.y_min_m
    step = width / CURRENT_COLUMNS
    rows = max(2, round(height / step))
    xs, ys = np.meshgrid(
        a.x_min_m + step * (np.arange(CURRENT_COLUMNS) + 0.5),
        a.y_min_m + height / rows * (np.arange(rows) + 0.5),
    )
    u, v = water.sample(t, xs, ys)
    fastest = float(np.max(np.hypot(u, v)))
    if fastest == 0.0:
        return
    ax.quiver(
        xs, ys, u, v, angles="xy", scale_units="xy", scale=fastest / (0.9 * step),
        color="tab:cyan", alpha=0.45, width=0.0022, zorder=0,
        label=f"current (max {fastest:.2f} m/s)",
    )  # fmt: skip


def _draw_vehicle(ax: Any, record: Record, scenario: Scenario, vid: str, colour: str) -> None:
    """One vehicle's planned paths, estimate, true trajectory, start and goal; a fleet
    vehicle (vid) all in its own colour, labelled by its id."""
    w = scenario.world
    truth: list[TruthState] = _of_type(record, TruthState, vid)
    paths = [p for p in distinct_paths(_of_type(record, PathMsg, vid)) if p.status == "OK"]
    if vid:
        for p in paths:
            xy = path_points(p, PATH_SAMPLES)
            ax.plot(xy[:, 0], xy[:, 1], "-", color=colour, lw=0.6, alpha=0.35)
        if truth:
            ax.plot(
                [q.x for q in truth], [q.y for q in truth], "-", color=colour, lw=1.6, label=vid
            )
        ax.plot(w.start.x_m, w.start.y_m, "o", color=colour, ms=6)
        ax.plot(w.goal.x_m, w.goal.y_m, "*", color=colour, ms=12)
        _mark_least_clearance(ax, truth, scenario, colour, vid)
        return
    _draw_plans(ax, paths, truth)
    est: list[StateEstimate] = _of_type(record, StateEstimate, vid)
    if est:
        ax.plot(
            [e.x for e in est], [e.y for e in est], "--", color="tab:orange", lw=1, label="estimate"
        )
    if truth:
        ax.plot(
            [q.x for q in truth],
            [q.y for q in truth],
            "-",
            color="tab:blue",
            lw=1.2,
            label="true trajectory",
        )
    ax.plot(w.start.x_m, w.start.y_m, "o", color="black", ms=7, label="start")
    ax.plot(w.goal.x_m, w.goal.y_m, "*", color="tab:red", ms=13, label="goal")
    ax.add_patch(
        shape(
            "Circle",
            (w.goal.x_m, w.goal.y_m),
            w.goal_tolerance_m,
            fc="none",
            ec="tab:red",
            lw=0.8,
        )
    )
    _mark_least_clearance(ax, truth, scenario, "tab:blue", "")


def _draw_plans(ax: Any, paths: list[PathMsg], truth: list[TruthState]) -> None:
    """Every plan faint over its whole length; bold, the part of each that was in force as
    the vehicle flew it (the path it followed); where each replan took over, a tick labelled
    with its reason's first word (one label for a run of replans of the same reason close
    together, e.g. "current x4")."""
    drawn = [(p, path_points(p, PATH_SAMPLES)) for p in paths]
    for i, (_, xy) in enumerate(drawn):
        ax.plot(
            xy[:, 0], xy[:, 1], "-", color="tab:green", lw=0.8, alpha=0.35,
            label="planned paths, as planned" if i == 0 else None,
        )  # fmt: skip
    parts = [xy for xy in flown_parts(drawn, truth) if len(xy) > 1]
    for i, xy in enumerate(parts):
        ax.plot(
            xy[:, 0], xy[:, 1], "-", color="tab:green", lw=3.6, alpha=0.75,
            label="path in force, as flown" if i == 0 else None,
        )  # fmt: skip
    for k, (where, text) in enumerate(replan_labels(drawn)):
        ax.plot(*where, "|", color="darkgreen", ms=8, mew=1.5)
        ax.annotate(
            text, xy=where, xytext=(0, 9 if k % 2 == 0 else -15), textcoords="offset points",
            ha="center", fontsize=7, color="darkgreen",
            bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none", "alpha": 0.7},
        )  # fmt: skip


def flown_parts(
    drawn: list[tuple[PathMsg, np.ndarray]], truth: list[TruthState]
) -> list[np.ndarray]:
    """Of each plan (its samples, (n, 2)), the samples it was in force over: those nearest
    the true positions from its stamp until the next plan's, first to last; (0, 2) for a plan
    replaced before the vehicle moved on it."""
    if not truth or not drawn:
        return [np.empty((0, 2)) for _ in drawn]
    t = np.array([q.stamp for q in truth])
    pos = np.array([(q.x, q.y) for q in truth])
    ends = [p.stamp for p, _ in drawn[1:]] + [np.inf]
    out = []
    for (p, xy), end in zip(drawn, ends, strict=True):
        here = pos[(t >= p.stamp) & (t <= end)]  # to where the next took over
        if not len(here):
            out.append(np.empty((0, 2)))
            continue
        # the sample of the plan nearest each position: (positions, samples) distances
        nearest = np.argmin(np.hypot(*(here[:, None, :] - xy[None, :, :]).transpose(2, 0, 1)), 1)
        out.append(xy[int(nearest.min()) : int(nearest.max()) + 1])
    return out


def reason_word(reason: str) -> str:
    """A replan's reason in one word: its first ("infeasible: ..." is "infeasible")."""
    found = re.match(r"\w+", reason.strip())
    return found.group(0) if found else "replan"


def replan_labels(drawn: list[tuple[PathMsg, np.ndarray]]) -> list[tuple[tuple[float, float], str]]:
    """Where each replan took over (its path's first point) and its reason's first word; a
    replan of the same reason within LABEL_MERGE_M of the last label joins it ("current x4")."""
    labels: list[tuple[tuple[float, float], str, int]] = []
    for p, xy in drawn[1:]:
        where, word = (float(xy[0, 0]), float(xy[0, 1])), reason_word(p.reason)
        if labels:
            (lx, ly), last, n = labels[-1]
            if last == word and np.hypot(where[0] - lx, where[1] - ly) <= LABEL_MERGE_M:
                labels[-1] = ((lx, ly), last, n + 1)
                continue
        labels.append((where, word, 1))
    return [(where, word if n == 1 else f"{word} x{n}") for where, word, n in labels]


def _mark_least_clearance(
    ax: Any, truth: list[TruthState], scenario: Scenario, colour: str, vid: str
) -> None:
    """A cross where the hull came nearest an obstacle (eq. (12), as min_clearance_m), rimmed
    in red when inside rho0; labelled with the clearance and the time (a fleet vehicle's,
    `vid`, only when inside rho0: the fleet's legend explains its crosses once)."""
    if not truth:
        return
    t, x, y = (np.array([getattr(q, k) for q in truth]) for k in ("stamp", "x", "y"))
    clear = World(scenario.world).clearance_many(x, y, scenario.vehicle.radius_m, t)
    i = int(np.argmin(clear))
    if not np.isfinite(clear[i]):
        return  # nothing in the water to come near
    inside = bool(clear[i] < scenario.planner.rho0_m)
    label = None if vid else "nearest an obstacle" + (" (inside rho0)" if inside else "")
    ax.plot(
        x[i], y[i], "X", color=colour, mec="tab:red" if inside else "white", mew=1.2, ms=9,
        label=label,
    )  # fmt: skip
    if vid and not inside:
        return
    _label(
        ax,
        scenario,
        (f"{vid}: " if vid else "")
        + f"{clear[i]:.2f} m from an obstacle, t = {t[i]:.1f} s"
        + (f": {scenario.planner.rho0_m - clear[i]:.2f} m inside rho0" if inside else ""),
        (float(x[i]), float(y[i])),
    )


def _label(ax: Any, scenario: Scenario, text: str, xy: tuple[float, float]) -> None:
    """A boxed note by the point xy, on the side of it towards the area's centre (so that it
    stays inside the drawn area, which the figure keeps its size for)."""
    a = scenario.world.area
    right = xy[0] > (a.x_min_m + a.x_max_m) / 2
    top = xy[1] > (a.y_min_m + a.y_max_m) / 2
    ax.annotate(
        text,
        xy=xy,
        xytext=(-8 if right else 8, -14 if top else 10),
        textcoords="offset points",
        ha="right" if right else "left",
        fontsize=8,
        bbox={"boxstyle": "round", "fc": "white", "ec": "0.6", "alpha": 0.85},
    )


def _draw_fleet_timing(ax: Any, record: Record, scenario: Scenario) -> None:
    """When the vehicles were where: a dot on every truth track each TIME_MARK_S (dots of the
    same rank are the same instant: crossing tracks are a conflict only if their dots meet),
    and the closest approach of two hulls, joined and labelled with its gap and time; the
    legend entry of every vehicle's cross nearest an obstacle."""
    truths = fleet_truths(record, scenario)
    for k, (vid, _) in enumerate(scenario.members):
        track = truths.get(vid)
        if track is None or len(track) < 2:
            continue
        marks = np.arange(TIME_MARK_S, track[-1, 0], TIME_MARK_S)
        ax.plot(
            np.interp(marks, track[:, 0], track[:, 1]),
            np.interp(marks, track[:, 0], track[:, 2]),
            ".",
            color=FLEET_COLOURS[k % len(FLEET_COLOURS)],
            ms=5,
        )
    ax.plot([], [], ".", color="0.3", ms=5, label=f"where each was every {TIME_MARK_S:g} s")
    w = scenario.world
    if w.circles or w.polygons or w.moving:  # in open water no vehicle has a cross
        ax.plot(
            [], [], "X", color="0.3", mec="tab:red", mew=1.2, ms=9,
            label="nearest an obstacle (red rim: inside rho0)",
        )  # fmt: skip
    near = closest_approach(record, scenario)
    if near is None:
        return
    (ax_, ay_), (bx_, by_) = near.a_xy, near.b_xy
    ax.plot([ax_, bx_], [ay_, by_], "k--", lw=1.0, label="closest approach")
    _label(
        ax,
        scenario,
        f"{near.a}-{near.b}: {near.gap_m:.2f} m hull to hull, t = {near.t_s:.1f} s",
        ((ax_ + bx_) / 2, (ay_ + by_) / 2),
    )
