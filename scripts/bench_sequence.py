"""Benchmark command sequences (issue 16): message size and controller step time vs horizon.

For each controller and horizon (0 = single commands, the baseline measured in the same run):
a PlannerCore on the default mission's first plan is fed estimates of a vehicle following it
(a slow lateral weave, no replans) and stepped at its control period; every step is timed on
this thread's CPU clock (the planner's whole step: prediction, controller rollout, message)
and every command encoded (the wire bytes, envelope included). Ratios are against horizon 0.

--model adds the accuracy of the planner's vehicle model (services/planner/response.py)
against the plant: on the default mission of each controller, the position predicted from
the true state under the commands the vehicle applied, after 0.5 to 5 s, for the model with
its speed and yaw lags, without them (the command at once, R_min kept), and the constant
twist the controllers' own compensation uses (controllers/base.py predict_pose).

    python scripts/bench_sequence.py [--steps 200] [--horizons 0,1,2,5,10] [--model]
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from common.config.scenario import Scenario, load_scenario
from common.messages import StateEstimate, TruthState, VelocityCommand, encode
from common.runtime.model.core import Delivery
from common.runtime.model.inproc import run_inproc
from services.planner.controllers import predict_pose
from services.planner.core import PlannerCore
from services.planner.response import ResponseModel

DEFAULT_SCENARIO = Path(__file__).resolve().parents[1] / "configs" / "default.toml"
CONTROLLERS = ("nurbs", "backstepping", "fuzzy_pid")
COV = tuple(0.01 if i % 6 == 0 else 0.0 for i in range(25))


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


def bench_steps(kind: str, horizon_s: float, steps: int) -> tuple[list[float], list[int]]:
    """(CPU seconds of each planner step, bytes of each command) along the first plan."""
    s = _scenario(kind, horizon_s)
    core = PlannerCore(s.planner, s.controller, s.vehicle, s.world, expected_downlink_s=0.05)
    start = s.world.start
    est = StateEstimate(
        stamp=0.0, x=start.x_m, y=start.y_m, theta=start.theta_rad, v=1.5, w=0.0, covariance=COV
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
            covariance=COV,
        )
        core.deliver(Delivery(source="estimator", stream="state", msg=est, t=t - 0.05))
        c0 = time.thread_time()
        out = core.step(t)
        dt = time.thread_time() - c0
        if any(e.stream == "path" for e in out):
            continue  # a replan's time is the planner benchmark's (scripts/bench_planner.py)
        (cmd,) = [e.msg for e in out if isinstance(e.msg, VelocityCommand)]
        times.append(dt)
        sizes.append(len(encode(cmd, source="planner", seq=k, sent=t)))
    return times, sizes


def main_steps(steps: int, horizons: list[float]) -> None:
    print(f"planner control step vs command horizon ({steps} steps, CPU time of this thread)")
    print(
        f"{'controller':13s} {'horizon s':>9s} {'entries':>7s} {'bytes':>6s} {'x bytes':>7s} "
        f"{'step p50 ms':>11s} {'p95 ms':>7s} {'x time':>7s}"
    )
    for kind in CONTROLLERS:
        base_t = base_b = math.nan
        for h in horizons:
            times, sizes = bench_steps(kind, h, steps)
            p50, p95 = (1e3 * float(np.percentile(times, q)) for q in (50, 95))
            size = float(np.median(sizes))
            if h == horizons[0]:
                base_t, base_b = p50, size
            n = _scenario(kind, h).controller.sequence.entries(0.1)
            print(
                f"{kind:13s} {h:9.1f} {n:7d} {size:6.0f} {size / base_b:7.1f} "
                f"{p50:11.2f} {p95:7.2f} {p50 / base_t:7.1f}"
            )


def _roll(
    model: ResponseModel, q: TruthState, h: float, ct: np.ndarray, vw: list[tuple[float, float]]
) -> tuple[float, float]:
    """The position h s after the true state q under the commands vw (applied from ct: (n,))."""
    pose = (q.x, q.y, q.theta, q.v, q.w)
    for j in range(round(h / 0.05)):
        i = int(np.searchsorted(ct, q.stamp + 0.05 * j, side="right")) - 1
        v, w = vw[i] if i >= 0 else (0.0, 0.0)
        pose = model.advance(pose, v, w, 0.05)
    return pose[0], pose[1]


def main_model(horizons: tuple[float, ...] = (0.5, 1.0, 2.0, 5.0)) -> None:
    """Prediction error of the planner's vehicle model against the plant (see module doc)."""
    print("vehicle model vs plant: position error after H s from the true state, under the")
    print("commands the vehicle applied (default mission, every 7th truth state)")
    print(f"{'controller':13s} {'H s':>4s} {'lags rms/max m':>15s} {'no lags':>15s} {'twist':>15s}")
    for kind in CONTROLLERS:
        s, _ = load_scenario(
            DEFAULT_SCENARIO,
            [f'controller.kind="{kind}"', "controller.sequence.horizon_s=0"],
        )
        rec = run_inproc(s).record
        truth = [q for q in rec.stream("vehicle", "truth") if isinstance(q, TruthState)]
        cmds = [c for c in rec.stream("planner", "cmd") if isinstance(c, VelocityCommand)]
        # applied from their delivery: the network's median one-way delay on this link
        ct = np.array([c.stamp + s.network.default.delay_s for c in cmds])
        vw = [(c.v, c.w) for c in cmds]
        lags = ResponseModel.from_vehicle(s.vehicle)
        instant = dataclasses.replace(lags, tau_v_s=0.0, tau_w_s=0.0)
        instant = dataclasses.replace(instant, accel_max_mps2=1e9, yaw_accel_max_rps2=1e9)

        for h in horizons:
            errs: dict[str, list[float]] = {"lags": [], "instant": [], "twist": []}
            for i in range(40, len(truth) - round(h / 0.05) - 1, 7):
                q, end = truth[i], truth[i + round(h / 0.05)]
                for name, m in (("lags", lags), ("instant", instant)):
                    x, y = _roll(m, q, h, ct, vw)
                    errs[name].append(math.hypot(x - end.x, y - end.y))
                p = predict_pose((q.x, q.y, q.theta, q.v, q.w), h)
                errs["twist"].append(math.hypot(p[0] - end.x, p[1] - end.y))
            cols = " ".join(
                f"{math.sqrt(np.mean(np.square(e))):7.3f}/{max(e):7.3f}" for e in errs.values()
            )
            print(f"{kind:13s} {h:4.1f} {cols}")


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    ap.add_argument(
        "--steps", type=int, default=200, help="control steps per (controller, horizon)"
    )
    ap.add_argument(
        "--horizons",
        default="0,1,2,5,10",
        help="command horizons (s), comma-separated; the first is the baseline",
    )
    ap.add_argument("--model", action="store_true", help="also the vehicle model's accuracy")
    args = ap.parse_args()
    main_steps(args.steps, [float(h) for h in args.horizons.split(",")])
    if args.model:
        main_model()
