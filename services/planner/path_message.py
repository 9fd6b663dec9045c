"""The path message a plan is published as: the NURBS on the wire, or a NO_PATH with its reason."""

from __future__ import annotations

import numpy as np

from common.messages import PathMsg
from services.planner.result import PlanResult


def _flat(a: np.ndarray) -> tuple[float, ...]:
    return tuple(float(v) for v in np.asarray(a, dtype=np.float64).ravel())


def path_message(
    result: PlanResult, *, stamp: float, path_id: int, status_since: float, why: str, v_ref: float
) -> PathMsg:
    """`result` as path `path_id`, asked for `why` and followed at v_ref (m/s), stamped when
    it is sent, with its reason codes (reasons.py); a NO_PATH carries its reason and no curve."""
    if result.ok:
        return PathMsg(
            stamp=stamp,
            path_id=path_id,
            status="OK",
            status_since=status_since,
            reason=f"{why}: {result.reason}" if result.reason else why,
            strategy=result.strategy,
            rejected=result.rejected,
            degree=result.degree,
            control_points=_flat(result.control_points),
            weights=_flat(result.weights),
            knots=_flat(result.knots),
            waypoints=_flat(result.grid_path),
            length=result.length_m,
            f_l=result.f_l,
            max_curvature=result.max_curvature,
            v_ref=v_ref,
        )
    return PathMsg(
        stamp=stamp,
        path_id=path_id,
        status="NO_PATH",
        status_since=status_since,
        reason=f"{why}: {result.reason}",
        strategy=result.strategy,
        rejected=result.rejected,
        degree=0,
        control_points=(),
        weights=(),
        knots=(),
        waypoints=(),
        length=0.0,
        f_l=0.0,
        max_curvature=0.0,
        v_ref=0.0,
    )
