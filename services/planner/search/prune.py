"""Any-angle waypoints: the optimal grid path pruned by line-of-sight shortcuts (Theta*'s test).

Any-angle paths come from pruning the optimal grid path with line-of-sight shortcuts that
use Theta*'s parent test (a shortcut must be free and no dearer than the grid path it
replaces). Theta* itself is not implemented: its per-expansion line-of-sight and
cost-integral checks in Python cost far more than Dijkstra in C plus this pruning
(docs/notes/planner-dijkstra-and-pruning-not-theta-star.md); the NURBS refinement
straightens the path further anyway.
"""

from __future__ import annotations

import math

import numpy as np

from common.world.geometry import FloatArray
from services.planner.search.costmap import CostMap
from services.planner.search.graph import GridPath


def segment_cost(cmap: CostMap, a: FloatArray, b: FloatArray) -> float:
    """Cost-weighted length of the straight segment a->b (inf if it crosses an occupied cell).

    Sampled every resolution/3, so a segment cannot skip a whole cell.
    """
    length = float(np.hypot(*(b - a)))
    n = max(2, int(math.ceil(3.0 * length / cmap.resolution_m)) + 1)
    t = np.linspace(0.0, 1.0, n)[:, None]
    cells = cmap.lookup(a[None, :] * (1.0 - t) + b[None, :] * t)
    if cmap.blocked.ravel()[cells].any():
        return math.inf
    return length * (1.0 + float(cmap.cost.ravel()[cells].mean()))


def prune_path(
    cmap: CostMap, path: GridPath, start_xy: FloatArray, goal_xy: FloatArray
) -> FloatArray:
    """Any-angle waypoints (k, 2): greedy line-of-sight shortcuts over the grid path.

    Like Theta*'s parent test, a shortcut from anchor i to node j is taken only if it is
    free and no dearer than the grid path it replaces (g[j] - g[i], 1% slack for sampling);
    so shortcuts never cut through the repulsive field to hug an obstacle.
    Candidates are the nodes where the grid path turns (plus the goal).
    """
    cells = path.cells
    pts = cmap.centre(cells % cmap.nx, cells // cmap.nx)
    pts[0], pts[-1] = start_xy, goal_xy
    if len(cells) <= 2:
        return pts
    steps = np.diff(np.stack([cells % cmap.nx, cells // cmap.nx], axis=1), axis=0)
    turn = np.any(steps[1:] != steps[:-1], axis=1)
    cand = np.concatenate([np.flatnonzero(turn) + 1, [len(cells) - 1]])
    keep = [0]
    anchor = last_ok = 0

    def shortcut_ok(i: int, j: int) -> bool:
        budget = (path.g[j] - path.g[i]) * 1.01 + 1e-9
        return segment_cost(cmap, pts[i], pts[j]) <= budget

    for j in cand.tolist():
        if shortcut_ok(anchor, j):
            last_ok = j
            continue
        if last_ok != anchor:
            keep.append(last_ok)
            anchor = last_ok
        if not shortcut_ok(anchor, j):
            # consecutive turning points are joined by one straight run of valid arcs
            keep.append(j)
            anchor = j
        last_ok = j
    if keep[-1] != len(cells) - 1:
        keep.append(len(cells) - 1)
    return pts[np.array(keep)]
