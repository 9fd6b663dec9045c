"""`tidelink monitor` against real launches: no run, and one following run after run. A
monitor joining a realtime run late, and one frozen beside it, are tests/test_live_run.py's;
one frozen beside a lockstep run is tests/test_lockstep_adversaries.py's.

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
