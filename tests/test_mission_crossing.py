"""The crossing scenario (configs/experiments/scenarios/crossing.toml, issue 15 finding 5):
moving obstacles cross the vehicle's way when it gets there; the NURBS method replans around
them, reaches the goal and keeps rho0 from every obstacle (eq. (12)-(13), against truth)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from helpers.runs import inproc

from common.config.scenario import Scenario, load_scenario
from common.messages import ObstacleTracks, PathMsg, TruthState
from common.runtime.distributed.lockstep import run_lockstep
from common.runtime.model.inproc import run_inproc
from common.runtime.model.record import Record
from common.world import World

CROSSING = Path(__file__).resolve().parents[1] / "configs/experiments/scenarios/crossing.toml"


def _truth(record: Record) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    truth = [m for m in record.stream("vehicle", "truth") if isinstance(m, TruthState)]
    return (
        np.array([m.stamp for m in truth]),
        np.array([m.x for m in truth]),
        np.array([m.y for m in truth]),
    )


def _clearance(s: Scenario, record: Record, world: World | None = None) -> np.ndarray:
    """Hull surface to obstacle surface along the true trajectory (eq. (12), World's model)."""
    t, x, y = _truth(record)
    return (world or World(s.world)).clearance_many(x, y, s.vehicle.radius_m, t)


@pytest.mark.heavy
def test_each_obstacle_crosses_the_way_when_the_vehicle_gets_there() -> None:
    # a vehicle that never sees the moving obstacles (the world without them) drives the
    # straight way; judged against each obstacle alone, every one of them would hit it
    s, _ = load_scenario(CROSSING)
    blind, _ = load_scenario(CROSSING, ["world.moving=[]"])
    run = run_inproc(blind)
    assert run.reason == "goal"
    assert len(s.world.moving) == 3
    for o in s.world.moving:
        alone = World(dataclasses.replace(s.world, moving=(o,)))
        assert _clearance(s, run.record, alone).min() < 0.0, f"obstacle {o.id} misses"


@pytest.mark.heavy
@pytest.mark.parametrize("seed", [1, 2])
def test_the_nurbs_method_replans_around_them_and_keeps_rho0(seed: int) -> None:
    s, _ = load_scenario(CROSSING, ['controller.kind="nurbs"'], seed=seed)
    r = inproc(s)
    assert r.reason == "goal" and r.metrics.success is True
    # never closer than rho0, hull surface to obstacle surface, against the true obstacles
    assert _clearance(s, r.record).min() >= s.planner.rho0_m
    paths = [m for m in r.record.stream("planner", "path") if isinstance(m, PathMsg)]
    # the first plan waited for the first tracks: it was made once a track was in
    tracked = [
        m.stamp
        for m in r.record.stream("estimator", "tracks")
        if isinstance(m, ObstacleTracks) and m.tracks
    ]
    assert tracked and paths[0].stamp > tracked[0]
    # and the moving obstacles forced replans (eq. (12)-(13) at the time the vehicle passes)
    events = {p.reason.split(":")[0] for p in paths[1:]}
    assert events & {"corridor", "infeasible"}, [p.reason for p in paths]


@pytest.mark.deterministic
@pytest.mark.slow
def test_crossing_lockstep_equals_inproc(tmp_path: Path) -> None:
    # the first 25 s: the first plan, made once the first tracks are in, and the replans for
    # the first obstacle (1.7-6.7 s) and for the two beyond sonar range at the start (~23 s)
    s, raw = load_scenario(CROSSING, ["run.max_time_s=25"])
    ref = run_inproc(s)
    got = run_lockstep(s, raw, tmp_path / "logs")
    assert got.metrics == ref.metrics and got.reason == ref.reason
    paths = [m for m in got.record.stream("planner", "path") if isinstance(m, PathMsg)]
    assert len(paths) >= 2  # it replanned within them
    assert got.record.stream("planner", "path") == ref.record.stream("planner", "path")
