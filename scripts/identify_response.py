"""The response model's mismatch with the plant, and its lags identified from the plant's steps.

The planner and the controllers predict the vehicle with their own model
(services/control/command/response.py), which never imports the plant: this tool, above both,
compares them. Under `vehicle.model = "fossen3dof"` the hull's yaw loop (the rudder's rate
limit, the hull's yaw inertia) reverses a turn in about a second, where the model's lags (the
unicycle's: yaw_tau_s 0.5 s, yaw_accel_max_rps2 0.5) do it in half that. `mismatch` measures
how far the model strays over step trials, and `identify` fits the lags to the plant, as a
trials engineer fits a manoeuvring model to zig-zag and acceleration runs:
- yaw: steps of the yaw-rate command at cruise speed, the heading of model and plant compared
  over YAW_WINDOW_S (vehicle.yaw_tau_s, vehicle.yaw_accel_max_rps2);
- speed: steps of the speed command, the distance run compared over SPEED_WINDOW_S
  (vehicle.accel_max_mps2; the speed loop's time constant stays m_eff / k_p).
configs/ocean.toml keeps the unicycle's lags: the identified ones were flown and changed no
outcome for the better (docs/notes/0061-response-model-identified-not-adopted.md).

    python scripts/identify_response.py configs/ocean.toml
"""

from __future__ import annotations

import argparse
import itertools
from collections.abc import Sequence
from dataclasses import dataclass, replace

from common.config.scenario import load_scenario
from common.config.vehicle import VehicleConfig
from services.control.command.response import ResponseModel
from services.vehicle.plant import make_plant

# (yaw rate before, after) (rad/s) at cruise speed: turns begun, ended and reversed
YAW_STEPS: tuple[tuple[float, float], ...] = (
    (0.0, 0.1), (0.0, 0.2), (0.2, 0.0), (0.1, -0.1), (0.19, -0.2), (-0.2, 0.2),
)  # fmt: skip
# (speed before, after) (m/s): speeding up, slowing down, stopping
SPEED_STEPS: tuple[tuple[float, float], ...] = (
    (0.3, 1.5), (1.0, 1.5), (1.5, 2.0), (1.5, 0.5), (1.5, 0.0),
)  # fmt: skip
YAW_WINDOW_S = 4.0  # a turn's start is over by then (both settle in ~2 s)
SPEED_WINDOW_S = 10.0  # a stop from cruise takes ~8 s
SETTLE_S = 10.0  # the plant held at the first command before the step
SAMPLE_S = 0.05  # the model's step, and how often both are compared

YAW_TAUS = tuple(round(0.30 + 0.05 * i, 2) for i in range(15))  # 0.30 .. 1.00 s
YAW_ACCELS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5, 0.7, 1.0)  # rad/s^2
ACCELS = (0.1, 0.15, 0.2, 0.25, 0.3, 0.4, 0.5)  # m/s^2


@dataclass(frozen=True)
class Mismatch:
    """How far the model strays from the plant over the steps: the worst heading error (rad)
    over the yaw steps, the worst along-track error (m) over the speed steps."""

    heading_rad: float
    along_m: float


@dataclass(frozen=True)
class Trials:
    """The plant's responses to the steps, sampled every SAMPLE_S from the step on: headings
    (rad, from the step's) and distances run (m)."""

    headings: tuple[tuple[float, ...], ...]
    runs: tuple[tuple[float, ...], ...]


def plant_trials(vehicle: VehicleConfig) -> Trials:
    """Run the steps on the plant vehicle.model names, in still water (the same for any model
    lags under fossen3dof: its plant does not read them)."""
    plant = make_plant(vehicle)
    h = vehicle.dt_internal_s
    per_sample = round(SAMPLE_S / h)
    v = vehicle.cruise_speed_mps

    def respond(
        v0: float, w0: float, v1: float, w1: float, window: float
    ) -> list[tuple[float, ...]]:
        s = plant.initial(0.0, 0.0, 0.0, v0, 0.0, w0)
        t = 0.0
        for _ in range(round(SETTLE_S / h)):
            s = plant.step(s, h, t, v0, w0)
            t += h
        out: list[tuple[float, ...]] = []
        for k in range(round(window / h) + 1):
            if k % per_sample == 0:
                out.append(plant.motion(s))
            s = plant.step(s, h, t, v1, w1)
            t += h
        return out

    headings = []
    for w0, w1 in YAW_STEPS:
        m = respond(v, w0, v, w1, YAW_WINDOW_S)
        headings.append(tuple(p[2] - m[0][2] for p in m))
    runs = []
    for v0, v1 in SPEED_STEPS:
        m = respond(v0, 0.0, v1, 0.0, SPEED_WINDOW_S)
        runs.append(tuple(p[0] - m[0][0] for p in m))
    return Trials(tuple(headings), tuple(runs))


def _model_samples(
    model: ResponseModel, start: tuple[float, float], command: tuple[float, float], n: int, i: int
) -> list[float]:
    """Coordinate i of the model's state (0: x, 2: heading), n + 1 samples from a twist
    `start` (v, w) under `command` (v, w)."""
    pose = (0.0, 0.0, 0.0, *start)
    out = []
    for _ in range(n + 1):
        out.append(pose[i])
        pose = model.advance(pose, *command, SAMPLE_S)
    return out


def _errors(model: ResponseModel, v: float, trials: Trials) -> tuple[list[float], list[float]]:
    """Per sample, heading errors over the yaw steps and distance errors over the speed steps."""
    dh: list[float] = []
    for (w0, w1), plant in zip(YAW_STEPS, trials.headings, strict=True):
        ours = _model_samples(model, (v, w0), (v, w1), len(plant) - 1, 2)
        dh += [a - b for a, b in zip(ours, plant, strict=True)]
    dx: list[float] = []
    for (v0, v1), plant in zip(SPEED_STEPS, trials.runs, strict=True):
        ours = _model_samples(model, (v0, 0.0), (v1, 0.0), len(plant) - 1, 0)
        dx += [a - b for a, b in zip(ours, plant, strict=True)]
    return dh, dx


def mismatch(vehicle: VehicleConfig, trials: Trials | None = None) -> Mismatch:
    """How far the response model of `vehicle` strays from its plant over the steps."""
    model = ResponseModel.from_vehicle(vehicle)
    trials = plant_trials(vehicle) if trials is None else trials
    dh, dx = _errors(model, vehicle.cruise_speed_mps, trials)
    return Mismatch(max(map(abs, dh)), max(map(abs, dx)))


def identify(vehicle: VehicleConfig, trials: Trials | None = None) -> VehicleConfig:
    """`vehicle` with the model's lags that fit its plant best (least squares over the steps,
    on the grids YAW_TAUS x YAW_ACCELS and ACCELS)."""
    trials = plant_trials(vehicle) if trials is None else trials
    base = ResponseModel.from_vehicle(vehicle)
    v = vehicle.cruise_speed_mps

    def yaw_cost(tau_accel: tuple[float, float]) -> float:
        model = replace(base, tau_w_s=tau_accel[0], yaw_accel_max_rps2=tau_accel[1])
        return sum(e * e for e in _errors(model, v, trials)[0])

    def speed_cost(accel: float) -> float:
        return sum(e * e for e in _errors(replace(base, accel_max_mps2=accel), v, trials)[1])

    tau, yaw_accel = min(itertools.product(YAW_TAUS, YAW_ACCELS), key=yaw_cost)
    accel = min(ACCELS, key=speed_cost)
    return replace(vehicle, yaw_tau_s=tau, yaw_accel_max_rps2=yaw_accel, accel_max_mps2=accel)


def main(argv: Sequence[str] | None = None) -> None:
    """Print a scenario's model lags and mismatch, and the identified ones."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", help="scenario TOML, e.g. configs/ocean.toml")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE")
    args = ap.parse_args(argv)
    vehicle = load_scenario(args.scenario, args.set)[0].vehicle
    if vehicle.model == "unicycle":
        raise SystemExit(
            "vehicle.model = 'unicycle': the plant is this model's own form, its lags are the "
            "plant's (nothing to identify); try --set 'vehicle.model=\"fossen3dof\"'"
        )
    trials = plant_trials(vehicle)  # run once: the fitted lags are the model's, not the hull's
    fitted = identify(vehicle, trials)
    print(f"plant: vehicle.model = {vehicle.model!r}")
    for label, cfg in (("configured", vehicle), ("identified", fitted)):
        m = mismatch(cfg, trials)
        print(
            f"{label:>10}: yaw_tau_s = {cfg.yaw_tau_s}, yaw_accel_max_rps2 = "
            f"{cfg.yaw_accel_max_rps2}, accel_max_mps2 = {cfg.accel_max_mps2}: heading off by "
            f"up to {m.heading_rad:.3f} rad, distance run by up to {m.along_m:.2f} m"
        )


if __name__ == "__main__":
    main()
