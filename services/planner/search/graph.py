"""Shortest path on the weighted directed grid graph of eq. (15)-(16) (Dijkstra, or A*).

Nodes are grid cells; arcs join a cell to its 8 or 16 neighbours with weight
d<v_i, v_j> = Euclidean length * (1 + mean repulsive cost of the cells the arc crosses), and
infinity when any crossed (or corner-cut) cell is occupied. The graph is a CSR matrix with a
fixed K slots per node, so only the weights are recomputed per replan (vectorised slicing);
Dijkstra then runs in C (scipy.sparse.csgraph). A pure-Python A* over the same arrays
(heapq, flat integer indices) is kept as an alternative and cross-check.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import dijkstra

from common.world.geometry import FloatArray
from services.planner.search.costmap import CostMap

IntArray = NDArray[np.intp]

_ORTHO = [(1, 0), (0, 1), (-1, 0), (0, -1)]
_DIAG = [(1, 1), (-1, 1), (-1, -1), (1, -1)]
_KNIGHT = [(1, 2), (2, 1), (-1, 2), (-2, 1), (-1, -2), (-2, -1), (1, -2), (2, -1)]


def _crossed(dx: int, dy: int) -> list[tuple[int, int]]:
    """Cells an arc from (0, 0) to (dx, dy) crosses or cuts the corner of (all must be free)."""
    if abs(dx) + abs(dy) == 1:
        return [(0, 0), (dx, dy)]
    if abs(dx) == abs(dy) == 1:
        return [(0, 0), (dx, dy), (dx, 0), (0, dy)]
    sx, sy = int(math.copysign(1, dx)), int(math.copysign(1, dy))
    if abs(dy) == 2:
        return [(0, 0), (0, sy), (dx, sy), (dx, dy)]
    return [(0, 0), (sx, 0), (sx, dy), (dx, dy)]


def directions(connectivity: int) -> list[tuple[int, int]]:
    return _ORTHO + _DIAG + (_KNIGHT if connectivity == 16 else [])


@lru_cache(maxsize=8)
def _structure(nx: int, ny: int, connectivity: int) -> tuple[IntArray, IntArray]:
    """CSR column indices (ny, nx, K) and row pointers; out-of-grid slots are self-loops."""
    dirs = directions(connectivity)
    iy, ix = np.mgrid[0:ny, 0:nx]
    own = iy * nx + ix
    cols = np.empty((ny, nx, len(dirs)), dtype=np.intp)
    for k, (dx, dy) in enumerate(dirs):
        jx, jy = ix + dx, iy + dy
        inside = (jx >= 0) & (jx < nx) & (jy >= 0) & (jy < ny)
        cols[:, :, k] = np.where(inside, jy * nx + jx, own)
    indptr = np.arange(0, nx * ny * len(dirs) + 1, len(dirs), dtype=np.intp)
    return cols, indptr


def edge_weights(cmap: CostMap, connectivity: int) -> FloatArray:
    """Eq. (15) arc weights (ny, nx, K) in metres of cost-weighted length; inf = no arc.

    An occupied cell carries cost inf, so any arc that crosses (or, diagonally, cuts the
    corner of) an occupied cell sums to inf without a separate mask.
    """
    dirs = directions(connectivity)
    nx, ny = cmap.nx, cmap.ny
    cost_inf = np.where(cmap.blocked, np.inf, cmap.cost)
    wall_inf = np.where(cmap.blocked, np.inf, 0.0)
    # written in the CSR layout (ny, nx, K) at once: a (K, ny, nx) array transposed into it
    # after cost a copy that took twice the loop (1.7 -> 0.6 ms a call on the ocean's grid)
    w = np.full((ny, nx, len(dirs)), np.inf)
    for k, (dx, dy) in enumerate(dirs):
        x0, x1 = max(0, -dx), nx - max(0, dx)
        y0, y1 = max(0, -dy), ny - max(0, dy)
        if x0 >= x1 or y0 >= y1:
            continue
        cells = _crossed(dx, dy)
        diagonal = abs(dx) == abs(dy)
        n_cost = 2 if diagonal else len(cells)  # diagonal: cost of the two end cells
        acc = np.zeros((y1 - y0, x1 - x0))
        for i, (ox, oy) in enumerate(cells):
            src = cost_inf if i < n_cost else wall_inf
            acc += src[y0 + oy : y1 + oy, x0 + ox : x1 + ox]
        length = math.hypot(dx, dy) * cmap.resolution_m
        w[y0:y1, x0:x1, k] = length * (1.0 + acc / n_cost)
    return w


@dataclass(frozen=True, eq=False)
class GridPath:
    """A node sequence of eq. (15) with the cost-to-come g of each node (eq. (16) weights)."""

    cells: IntArray  # flat cell indices iy * nx + ix, start first
    g: FloatArray  # accumulated arc weights along the path (m), g[0] = 0


def shortest_path(
    cmap: CostMap, start: int, goal: int, connectivity: int, method: str = "dijkstra"
) -> GridPath | None:
    """Minimum-weight path from cell `start` to cell `goal`, or None if the goal is unreachable."""
    cols, indptr = _structure(cmap.nx, cmap.ny, connectivity)
    w = edge_weights(cmap, connectivity)
    if method == "astar":
        return _astar(cmap, w, cols, start, goal)
    n = cmap.nx * cmap.ny
    graph = csr_matrix((w.ravel(), cols.ravel(), indptr), shape=(n, n))
    dist, pred = dijkstra(graph, directed=True, indices=start, return_predecessors=True)
    if not np.isfinite(dist[goal]):
        return None
    cells = [goal]
    while cells[-1] != start:
        cells.append(int(pred[cells[-1]]))
    path = np.array(cells[::-1], dtype=np.intp)
    return GridPath(cells=path, g=dist[path])


def _astar(cmap: CostMap, w: FloatArray, cols: IntArray, start: int, goal: int) -> GridPath | None:
    """Textbook A* with heapq over flat indices; the Euclidean heuristic is admissible here
    because every arc weight is at least its length (cost >= 0)."""
    n, k_dirs = cmap.nx * cmap.ny, w.shape[2]
    gx, gy = goal % cmap.nx, goal // cmap.nx
    iy, ix = np.divmod(np.arange(n), cmap.nx)
    h = (np.hypot(ix - gx, iy - gy) * cmap.resolution_m).tolist()
    wl = w.reshape(n, k_dirs).tolist()
    cl = cols.reshape(n, k_dirs).tolist()
    g = [math.inf] * n
    parent = [-1] * n
    closed = bytearray(n)
    g[start] = 0.0
    heap = [(h[start], start)]
    while heap:
        _, i = heapq.heappop(heap)
        if closed[i]:
            continue
        if i == goal:
            break
        closed[i] = 1
        gi = g[i]
        for wij, j in zip(wl[i], cl[i], strict=True):
            ng = gi + wij
            if ng < g[j]:
                g[j] = ng
                parent[j] = i
                heapq.heappush(heap, (ng + h[j], j))
    if not math.isfinite(g[goal]):
        return None
    cells = [goal]
    while cells[-1] != start:
        cells.append(parent[cells[-1]])
    path = np.array(cells[::-1], dtype=np.intp)
    return GridPath(cells=path, g=np.array([g[c] for c in path]))
