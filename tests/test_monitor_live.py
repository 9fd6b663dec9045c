"""`tidelink monitor` against real launches: no run, a monitor that stops reading (SIGSTOP)
leaving a lockstep trajectory bit-identical, and one following run after run. A monitor
joining a realtime run late is tests/test_live_run.py's.

Everything is real: the launcher, its router and four service processes over Zenoh, and the
monitor as its own process. Waits are on lines the processes print, with timeouts.
"""

from __future__ import annotations

import json
import signal
from pathlib import Path
from typing import Any

import pytest
from helpers.launch_proc import Tidelink, judged_exit, kill_recorded
from helpers.runs import inproc

from common.config.scenario import load_scenario
from common.runtime.processes.children import free_port

pytestmark = pytest.mark.slow

WAIT_S = 60.0
SHORT = "configs/experiments/scenarios/short.toml"
SMALL = "configs/experiments/scenarios/small.toml"  # ~35 s to its goal


def _lines(t: Tidelink) -> list[dict[str, Any]]:
    return [json.loads(line) for line in t.stdout.splitlines() if line.startswith("{")]


def _metrics(out: Path) -> dict[str, Any]:
    return dict(json.loads((out / "metrics.json").read_text()))


@pytest.fixture
def out(tmp_path: Path) -> Any:
    d = tmp_path / "run"
    yield d
    kill_recorded(d / "pids.json")


def test_a_monitor_without_a_run_says_so_and_waits_or_exits_2(tmp_path: Path) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Tidelink("router", "--listen", endpoint) as router:
        router.wait_for(r"listening", WAIT_S, stdout=True)
        with Tidelink("monitor", "--connect", endpoint, "--json", "--no-wait") as mon:
            assert mon.wait(WAIT_S) == 2
        (notice,) = [x for x in _lines(mon) if x["type"] == "notice"]
        assert "no run" in notice["text"] and endpoint in notice["text"]
        with Tidelink("monitor", "--connect", endpoint, "--json", "--run", "nosuch") as mon:
            mon.wait_for(r"no run nosuch .* yet; waiting", 15.0, stdout=True)
            mon.signal(signal.SIGTERM)
            assert mon.wait(15.0) == 0  # a clean stop on SIGTERM
        router.signal(signal.SIGINT)
        router.wait(15.0)


def _with_a_stopped_monitor(launch: list[str], endpoint: str) -> tuple[int, str]:
    """Run a launch while a monitor that joined is SIGSTOPped; (launch exit code, stderr)."""
    with Tidelink(*launch) as run:
        run.wait_for(r"router listening", WAIT_S)
        with Tidelink("monitor", "--connect", endpoint, "--json", "--every", "0.1") as mon:
            mon.wait_for(r'"event": "joined"', WAIT_S, stdout=True)
            mon.signal(signal.SIGSTOP)  # it stops reading: its socket fills, the tap drops
            try:
                code = run.wait(WAIT_S * 2)
            finally:
                mon.signal(signal.SIGCONT)
        return code, run.stderr


@pytest.mark.deterministic
def test_a_sigstopped_monitor_leaves_a_lockstep_trajectory_bit_identical(
    tmp_path: Path, out: Path
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    # a slower lockstep run (the coordinator waits for a monitor-free wall pace anyway)
    launch = ["launch", SHORT, "--runtime", "lockstep", "--listen", endpoint, "--out", str(out)]
    code, err = _with_a_stopped_monitor(launch, endpoint)
    assert code == 0, err
    s, _ = load_scenario(SHORT)
    expected = inproc(s).metrics["trajectory_sha256"]
    assert _metrics(out)["trajectory_sha256"] == expected


def test_a_following_monitor_waits_for_a_router_and_watches_one_run_after_another(
    tmp_path: Path,
) -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with Tidelink("monitor", "--connect", endpoint, "--json", "--follow") as mon:
        mon.wait_for(r"no router at .* yet; waiting", 15.0, stdout=True)  # none listens yet
        for seed in ("1", "2"):  # each launch brings its own router on the same endpoint
            out = tmp_path / f"run{seed}"
            launch = ["launch", SMALL, "--runtime", "lockstep", "--listen", endpoint]
            launch += ["--set", "run.max_time_s=6"]  # a run's start and its end are what count
            with Tidelink(*launch, "--seed", seed, "--out", str(out), "--no-plot") as run:
                assert run.wait(WAIT_S) == judged_exit(out), run.stderr
        first = mon.wait_for(r'"event": "end"', WAIT_S, stdout=True).string
        second = mon.wait_for(
            r'"event": "end"', WAIT_S, start=mon.out.index(first) + 1, stdout=True
        )
        ends = [json.loads(first), json.loads(second.string)]
        assert [e["text"].endswith("max_time") for e in ends] == [True, True]
        assert mon.proc.poll() is None  # --follow: still watching
        mon.signal(signal.SIGINT)
        assert mon.wait(15.0) == 0
