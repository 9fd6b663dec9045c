"""Occupancy and repulsive-cost grid over the area: eq. (5)-(6) potential, eq. (17) smoothing."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import convolve1d

from common.config.planner import PlannerConfig, grid_shape
from common.config.world import AreaConfig
from common.world.geometry import FloatArray
from services.planner.geometry.clearance import StaticField

BoolArray = NDArray[np.bool_]


@dataclass(frozen=True, eq=False)
class CostMap:
    """A cell-centred grid: clearance, occupancy and cost. Row iy is y, column ix is x."""

    area: AreaConfig
    resolution_m: float
    nx: int
    ny: int
    clearance: FloatArray  # (ny, nx) centre-to-nearest-surface distance (m), capped far away
    static_clearance: FloatArray  # (ny, nx) the same for static obstacles only
    blocked: BoolArray  # (ny, nx) inside an obstacle inflated by r + rho0 (or off the area)
    cost: FloatArray  # (ny, nx) dimensionless repulsive cost after eq. (17) smoothing, >= 0

    def cell_of(self, x: float, y: float) -> tuple[int, int]:
        """(ix, iy) of the cell containing (x, y), clamped into the grid."""
        ix = int((x - self.area.x_min_m) / self.resolution_m)
        iy = int((y - self.area.y_min_m) / self.resolution_m)
        return min(max(ix, 0), self.nx - 1), min(max(iy, 0), self.ny - 1)

    def centre(self, ix: NDArray[np.intp], iy: NDArray[np.intp]) -> FloatArray:
        """World coordinates (k, 2) of cell centres."""
        x = self.area.x_min_m + (np.asarray(ix) + 0.5) * self.resolution_m
        y = self.area.y_min_m + (np.asarray(iy) + 0.5) * self.resolution_m
        return np.stack([x, y], axis=-1).astype(np.float64)

    def lookup(self, pts: FloatArray) -> NDArray[np.intp]:
        """Flat cell indices iy * nx + ix (k,) of points (k, 2), clamped into the grid
        (vectorised), into a grid's `ravel()`: one index array where a pair cost two (the
        line-of-sight shortcuts look up every segment they try: prune.py)."""
        ix = ((pts[:, 0] - self.area.x_min_m) / self.resolution_m).astype(np.intp)
        iy = ((pts[:, 1] - self.area.y_min_m) / self.resolution_m).astype(np.intp)
        ix = np.minimum(np.maximum(ix, 0), self.nx - 1)
        return np.minimum(np.maximum(iy, 0), self.ny - 1) * self.nx + ix

    def static_clearance_at(self, pts: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Bilinear interpolation of the static clearance (m,) and its gradient (m, 2).

        The clearance is 1-Lipschitz, so the interpolant is within resolution * sqrt(2) of
        the exact distance; the refinement uses it for speed, the final check uses exact
        geometry.
        """
        res = self.resolution_m
        gx = (pts[:, 0] - self.area.x_min_m) / res - 0.5
        gy = (pts[:, 1] - self.area.y_min_m) / res - 0.5
        ix = np.minimum(np.maximum(np.floor(gx).astype(np.intp), 0), self.nx - 2)
        iy = np.minimum(np.maximum(np.floor(gy).astype(np.intp), 0), self.ny - 2)
        fx = np.minimum(np.maximum(gx - ix, 0.0), 1.0)
        fy = np.minimum(np.maximum(gy - iy, 0.0), 1.0)
        # the four corners by flat index into the (contiguous) grid: one index array each
        # instead of two (the refinement asks this ~35 times a plan; ~20% of its cost)
        c = self.static_clearance.ravel()
        k = iy * self.nx + ix
        v00, v10 = c[k], c[k + 1]
        k += self.nx
        v01, v11 = c[k], c[k + 1]
        bottom = v00 + fx * (v10 - v00)
        top = v01 + fx * (v11 - v01)
        val = bottom + fy * (top - bottom)
        grad = np.empty((len(val), 2))
        grad[:, 0] = ((1.0 - fy) * (v10 - v00) + fy * (v11 - v01)) / res
        grad[:, 1] = (top - bottom) / res
        return val, grad


def smoothing_kernel(l_cells: int) -> FloatArray:
    """Eq. (17) filter: taps [1, 2, ..., 2, 1] over 2l+1 cells, normalised to unit sum.

    The printed eq. (17) reads h_k = (h_{k-l} + 2h_{k-l+1} + ... + 2h_{k+l-1}) / (2l+1), which
    is garbled: the closing h_{k+l} term is missing and 2l+1 does not normalise those weights.
    We read it as the symmetric 2l+1-tap kernel with end taps 1 and inner taps 2, divided by
    its sum 4l so a uniform density stays unchanged; it is applied separably along x and y.
    """
    if l_cells <= 0:
        return np.ones(1)
    k = np.full(2 * l_cells + 1, 2.0)
    k[0] = k[-1] = 1.0
    return k / k.sum()


def repulsive_cost(rho: FloatArray, cfg: PlannerConfig) -> FloatArray:
    """Eq. (6) F_rep as a cost: K_r (1/(rho-rho0)^2 - 1/(rho_m-rho0)^2) for rho <= rho_m.

    rho is the surface-to-surface distance (vehicle to obstacle). Eq. (6) diverges at rho0,
    where cells are occupied anyway, so the cost is capped at `cost_cap`.
    """
    gap = np.maximum(rho - cfg.rho0_m, 1e-9)
    f = cfg.k_r * (1.0 / (gap * gap) - 1.0 / (cfg.rho_m - cfg.rho0_m) ** 2)
    f = np.where(rho > cfg.rho_m, 0.0, f)
    return np.clip(f, 0.0, cfg.cost_cap)


def build_costmap(
    area: AreaConfig,
    static: StaticField,
    extra_discs: FloatArray,
    vehicle_radius_m: float,
    cfg: PlannerConfig,
) -> CostMap:
    """Clearance, occupancy and cost grid for the static field plus extra (predicted) discs.

    extra_discs: (k, 3) x, y, radius of each disc (m), e.g. from prediction.predicted_discs.

    Distances use exact geometry (circles and polygon edges), evaluated only in each obstacle's
    window of influence (bounding box grown by r + rho_m); beyond it nothing is blocked and
    eq. (5)-(6) give zero cost, so the clearance there is only a lower bound (reach).
    Exact geometry rather than a distance transform of a rasterised mask: it costs about the
    same here and is exact, where an EDT of cell centres is off by up to a cell diagonal and
    would not be a safe lower bound for the final check.
    """
    res = cfg.resolution_m
    grid = _Grid(area, res, vehicle_radius_m + cfg.rho_m + res)
    static_clear = _static_clearance(static, grid)
    clear = static_clear.copy()
    for cx, cy, cr in np.asarray(extra_discs, dtype=np.float64).reshape(-1, 3).tolist():
        grid.add_disc(clear, cx, cy, cr)

    rho = clear - vehicle_radius_m  # eq. (5): surface-to-surface distance
    blocked = rho < cfg.rho0_m  # inflated by r + rho0 -> occupied
    # the vehicle body must stay inside the area X (eq. (10))
    xs, ys = grid.xs, grid.ys
    edge_gap = np.minimum.outer(
        np.minimum(ys - area.y_min_m, area.y_max_m - ys),
        np.minimum(xs - area.x_min_m, area.x_max_m - xs),
    )
    blocked |= edge_gap < vehicle_radius_m
    cost = repulsive_cost(rho, cfg)
    if cfg.smoothing_len > 0:  # eq. (17), separable along both axes
        kern = smoothing_kernel(cfg.smoothing_len)
        cost = convolve1d(
            convolve1d(cost, kern, axis=0, mode="nearest"), kern, axis=1, mode="nearest"
        )
    cost = np.where(blocked, cfg.cost_cap, cost)
    return CostMap(
        area=area,
        resolution_m=res,
        nx=grid.nx,
        ny=grid.ny,
        clearance=clear,
        static_clearance=static_clear,
        blocked=blocked,
        cost=cost,
    )


class _Grid:
    """The cost map's cell centres (xs (nx,), ys (ny,)) and the window of cells within
    `reach` (m) of a box: the farthest distance that still matters."""

    def __init__(self, area: AreaConfig, res: float, reach: float) -> None:
        self.area, self.res, self.reach = area, res, reach
        self.nx, self.ny = grid_shape(area, res)
        self.xs = area.x_min_m + (np.arange(self.nx) + 0.5) * res
        self.ys = area.y_min_m + (np.arange(self.ny) + 0.5) * res

    def window(self, x0: float, y0: float, x1: float, y1: float) -> tuple[slice, slice]:
        a, res, reach = self.area, self.res, self.reach
        i0 = max(0, int((x0 - reach - a.x_min_m) / res))
        i1 = min(self.nx, int((x1 + reach - a.x_min_m) / res) + 2)
        j0 = max(0, int((y0 - reach - a.y_min_m) / res))
        j1 = min(self.ny, int((y1 + reach - a.y_min_m) / res) + 2)
        return slice(j0, j1), slice(i0, i1)

    def add_disc(self, clear: FloatArray, cx: float, cy: float, cr: float) -> None:
        """Lower `clear` (ny, nx) to each cell's distance to the disc (cx, cy, cr)."""
        sy, sx = self.window(cx - cr, cy - cr, cx + cr, cy + cr)
        if sy.start < sy.stop and sx.start < sx.stop:
            d = np.hypot(self.xs[None, sx] - cx, self.ys[sy, None] - cy) - cr
            clear[sy, sx] = np.minimum(clear[sy, sx], d)


def _static_clearance(static: StaticField, grid: _Grid) -> FloatArray:
    """Each cell's clearance (ny, nx) to the static obstacles, capped at grid.reach, read-only:
    built once per chart and grid (StaticField.grids), for an ask builds a cost map for every
    plan it makes, and the chart stays the same."""
    key = (grid.area, grid.res, grid.reach)
    kept = static.grids.get(key)
    if kept is not None:
        return kept
    # cells outside every window are farther than `reach` from all obstacles: the cap is a
    # lower bound of the true clearance, which the final check relies on
    clear = np.full((grid.ny, grid.nx), grid.reach)
    for cx, cy, cr in static.circ.tolist():
        grid.add_disc(clear, cx, cy, cr)
    n_circ = len(static.circ)
    for p in range(len(static.edges.starts)):
        sy, sx = grid.window(*static.bbox[n_circ + p])
        if sy.start >= sy.stop or sx.start >= sx.stop:
            continue
        gx, gy = np.meshgrid(grid.xs[sx], grid.ys[sy])
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1)
        d = static.polygon(p).signed_distances(pts)[:, 0]  # one polygon: no gradient needed
        clear[sy, sx] = np.minimum(clear[sy, sx], d.reshape(gx.shape))
    clear.setflags(write=False)
    static.grids[key] = clear
    return clear
