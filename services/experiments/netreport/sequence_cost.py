"""What command sequences cost: message size and planner step time against the horizon.

A PlannerCore on the default mission's first plan is fed estimates of a vehicle following it
(a slow lateral weave, no replans) and stepped at its control period, preparing its next step
after each one as every runtime has it do (core.Prepares); every step is timed on this
thread's CPU clock (what the command waits for: prediction, the entries computed on the newest
state, the message), and so is every prepare after it (the rest of the rollout, for the next
step: services/control/command/sequence.py, "Prepared tails"), and every command encoded (the wire
bytes, envelope included). Used by scripts/bench_sequence.py and by the networked-control
report (networked.py).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from common.config.scenario import Scenario, load_scenario
from common.messages import StateEstimate, VelocityCommand, encode
from common.runtime.model.core import Delivery
from services.mission.dataflow import command_loop
from services.planner.core import PlannerCore

DEFAULT_SCENARIO = Path(__file__).resolve().parents[3] / "configs" / "default.toml"
CONTROLLERS = ("nurbs", "backstepping", "fuzzy_pid")
HORIZONS_S = (0.0, 1.0, 2.0, 5.0, 10.0)
_COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))


@dataclass(frozen=True, kw_only=True)
class CostRow:
    """One (controller, horizon): entries, median message bytes, step time percentiles (ms),
    and the ratios to the first horizon measured in the same run (the baseline)."""

    controller: str
    horizon_s: float
    entries: int
    bytes: float
    bytes_ratio: float
    step_p50_ms: float
    step_p95_ms: float
    time_ratio: float
    prepare_p50_ms: float  # preparing the next step after each (0: nothing to prepare)


def _scenario(kind: str, horizon_s: float) -> Scenario:
    s, _ = load_scenario(
        DEFAULT_SCENARIO,
        [
            f'controller.kind="{kind}"',
            f"controller.sequence.horizon_s={horizon_s}",
            # off at every horizon: it costs one min() an entry, and horizons under the 5 s
            # it needs to brake from cruise are refused with it (common/config/scenario.py)
            "controller.sequence.stop_tail=false",
            "planner.first_plan_wait_s=0",
        ],
    )
    return s


def bench_steps(
    kind: str, horizon_s: float, steps: int, *, prepared: list[float] | None = None
) -> tuple[list[float], list[int]]:
    """(CPU seconds of each planner step, bytes of each command) along the first plan; the CPU
    seconds of preparing after each step are appended to `prepared`, if given."""
    s = _scenario(kind, horizon_s)
    loop = command_loop(s, logging.getLogger("tidelink.planner"), expected_downlink_s=0.05)
    core = PlannerCore(loop, s.planner, s.vehicle, s.world)
    start = s.world.start
    est = StateEstimate(
        stamp=0.0, x=start.x_m, y=start.y_m, theta=start.theta_rad, v=1.5, w=0.0, covariance=_COV
    )
    core.deliver(Delivery(source="estimator", stream="state", msg=est, t=0.0))
    core.step(0.05)  # the first plan (not timed: a replan, not a control step)
    ref = core.ref
    assert ref is not None
    times, sizes = [], []
    period = s.planner.period_s
    for k in range(1, steps + 1):
        t = 0.05 + k * period
        sk = min(1.5 * (t - 0.1), ref.length)
        x, y = ref.point_at_s(sk)
        th = ref.heading_at_s(sk)
        off = 0.3 * math.sin(0.3 * t)  # a slow lateral weave the controller corrects
        est = StateEstimate(
            stamp=t - 0.1,
            x=x - off * math.sin(th),
            y=y + off * math.cos(th),
            theta=th + 0.05 * math.cos(0.3 * t),
            v=1.5,
            w=1.5 * ref.curvature_at_s(sk),
            covariance=_COV,
        )
        core.deliver(Delivery(source="estimator", stream="state", msg=est, t=t - 0.05))
        c0 = time.thread_time()
        out = core.step(t)
        c1 = time.thread_time()
        core.prepare(0.05 + (k + 1) * period)  # the next step's time, as that step computes it
        c2 = time.thread_time()
        if any(e.stream == "path" for e in out):
            continue  # a replan's time is the planner benchmark's (scripts/bench_planner.py)
        (cmd,) = [e.msg for e in out if isinstance(e.msg, VelocityCommand)]
        times.append(c1 - c0)
        if prepared is not None:
            prepared.append(c2 - c1)
        sizes.append(len(encode(cmd, source="planner", seq=k, sent=t)))
    return times, sizes


def cost_table(steps: int = 200, horizons: tuple[float, ...] = HORIZONS_S) -> list[CostRow]:
    """Every controller at every horizon; the first horizon is the baseline of the ratios."""
    rows = []
    for kind in CONTROLLERS:
        base_t = base_b = math.nan
        for h in horizons:
            prepared: list[float] = []
            times, sizes = bench_steps(kind, h, steps, prepared=prepared)
            p50, p95 = (1e3 * float(np.percentile(times, q)) for q in (50, 95))
            size = float(np.median(sizes))
            if h == horizons[0]:
                base_t, base_b = p50, size
            s = _scenario(kind, h)
            rows.append(
                CostRow(
                    controller=kind,
                    horizon_s=h,
                    entries=s.controller.sequence.entries(s.planner.period_s),
                    bytes=size,
                    bytes_ratio=size / base_b,
                    step_p50_ms=p50,
                    step_p95_ms=p95,
                    time_ratio=p50 / base_t,
                    prepare_p50_ms=1e3 * float(np.median(prepared)) if prepared else 0.0,
                )
            )
    return rows
