"""Benchmark command sequences (issue 16): message size and controller step time vs horizon.

For each controller and horizon (0 = single commands, the baseline measured in the same run):
the planner's control step on the default mission's first plan, timed on this thread's CPU
clock, then its preparing the next step (the rest of the rollout, computed once the command
is out), and its command's wire bytes (services/experiments/netreport/sequence_cost.py, which the
networked-control report quotes too). Ratios are against the first horizon.

--model adds the accuracy of the planner's vehicle model (services/control/command/response.py)
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

import numpy as np

from common.config.scenario import load_scenario
from common.messages import TruthState, VelocityCommand
from common.runtime.model.inproc import run_inproc
from services.control.command.response import ResponseModel
from services.control.controllers import predict_pose
from services.experiments.netreport.sequence_cost import CONTROLLERS, DEFAULT_SCENARIO, cost_table


def main_steps(steps: int, horizons: list[float]) -> None:
    print(f"planner control step vs command horizon ({steps} steps, CPU time of this thread)")
    print(
        f"{'controller':13s} {'horizon s':>9s} {'entries':>7s} {'bytes':>6s} {'x bytes':>7s} "
        f"{'step p50 ms':>11s} {'p95 ms':>7s} {'x time':>7s} {'then prepare p50 ms':>19s}"
    )
    for r in cost_table(steps, tuple(horizons)):
        print(
            f"{r.controller:13s} {r.horizon_s:9.1f} {r.entries:7d} {r.bytes:6.0f} "
            f"{r.bytes_ratio:7.1f} {r.step_p50_ms:11.2f} {r.step_p95_ms:7.2f} {r.time_ratio:7.1f}"
            f" {r.prepare_p50_ms:19.2f}"
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
