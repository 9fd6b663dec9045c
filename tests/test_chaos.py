"""The standing fault matrix (services/chaos) in the test suite: a case of each kind a run
survives (a service killed and restarted, one stopped, hostile frames on every data key) on a
real launch, each judged by the same invariants as `tidelink chaos` (no hang, no process left,
metrics written, exit 0 only on success, success where the fault is survivable). Faults that
end a run (a service or the router killed for good, the launcher killed) are
tests/test_launcher.py's; `scripts/chaos` runs the whole matrix on the default mission."""

from __future__ import annotations

from pathlib import Path

import pytest

from common.config.scenario import load_scenario
from common.runtime.distributed.bringup import run_keys
from common.runtime.model.mission import load_mission
from services.chaos.case import CaseSetup, run_case
from services.chaos.faults import INJECTIONS, TICK_AHEAD_S, Fault, matrix
from services.chaos.forge import payloads
from services.chaos.verdict import problems, table

REPO = Path(__file__).resolve().parents[1]
# The short mission (~27 s) at 6x; the faults strike at t = 14 s, past circle 1, so an 8 s stop
# of the planner falls in open water (the vehicle runs on its command sequence)
SETUP = CaseSetup(
    scenario=REPO / "configs" / "experiments" / "scenarios" / "short.toml",
    fault_at_s=14.0,
    time_scale=6.0,
)
CASES = [
    Fault("kill", "planner", restart=True),
    Fault("stop", "planner"),
    Fault("inject", "hostile"),
    # from outside the loop (services/chaos/outside.py), the two that take a run's length: the
    # router's restart and a forged Tick; the watchers' 20 s freeze, duplicates and a replay
    # run in `tidelink chaos`
    Fault("kill", "router", restart=True),
    Fault("forge_tick", hold_s=TICK_AHEAD_S),
]


@pytest.mark.slow
@pytest.mark.exclusive  # its invariants are judged in real time
@pytest.mark.parametrize("fault", CASES, ids=lambda f: f.name.replace(" ", "-"))
def test_a_fault_case_keeps_every_invariant(fault: Fault, tmp_path: Path) -> None:
    scenario, _ = load_scenario(SETUP.scenario, [], None)
    flow = load_mission(scenario).dataflow
    outcome = run_case(SETUP, fault, tmp_path / "case", run_keys(scenario), flow)
    assert problems(outcome) == [], table([outcome])


def test_the_matrix_covers_every_service_the_router_the_launcher_and_every_injection() -> None:
    names = ("estimator", "planner", "sensor", "vehicle")
    faults = matrix(names)
    for s in (*names, "router"):
        assert Fault("kill", s) in faults and any(
            f.kind == "stop" and f.target == s for f in faults
        )
    for s in names:
        assert Fault("kill", s, restart=True) in faults
    assert {f.target for f in faults if f.kind == "inject"} == set(INJECTIONS)
    assert Fault("kill_launcher") in faults
    assert [f for f in faults if f.survivable is False] == [
        f for f in faults if f.kind == "kill_launcher" or (f.kind == "kill" and not f.restart)
    ]


def test_forged_payloads_are_what_they_say() -> None:
    from common.messages import NavFix, WireError, decode

    real = NavFix(
        stamp=12.0,
        seq=40,
        source="sensor",
        x=1.0,
        y=2.0,
        heading=0.1,
        speed=1.0,
        std_xy=0.5,
        std_heading=0.01,
        std_speed=0.05,
    )
    for mode in ("future", "unix", "seq_jump", "extreme"):
        msg = decode(payloads(mode, real)[0])  # well-formed: they pass the decoder, to the cores
        assert isinstance(msg, NavFix) and msg.source == "sensor"
    assert decode(payloads("extreme", real)[0]).x == 1e300
    assert decode(payloads("future", real)[0]).stamp == 12.0 + 1e6
    assert decode(payloads("seq_jump", real)[0]).seq == 2**62
    for data in payloads("non_finite", real) + payloads("malformed", real):
        with pytest.raises(WireError):
            decode(data)
