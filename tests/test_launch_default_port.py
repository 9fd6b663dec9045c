"""`tidelink launch` without --listen listens where the watchers look by default (7447 on
loopback), so a plain `tidelink monitor` meets it; when 7447 is taken, before the router
starts or as it starts (another launch won the race), the launch takes a free port and
says so.

The meeting runs in a network namespace of its own, whose loopback has 7447 free whatever
else this machine runs; the fall-backs run against a port this test holds.
"""

from __future__ import annotations

import json
import socket
from collections.abc import Iterator
from pathlib import Path

import pytest
from helpers.launch_proc import REPO, Tidelink, judged_exit, kill_recorded
from helpers.netns import lab_or_skip

from common.config.bus import DEFAULT_CONNECT
from common.runtime.processes.supervisor import Supervisor
from services.launcher import router

WAIT_S = 60.0
SMALL = str(REPO / "configs" / "experiments" / "scenarios" / "small.toml")


@pytest.fixture
def held_port() -> Iterator[int]:
    """A loopback port something listens on for the test's length."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        yield int(s.getsockname()[1])


def _start(tmp_path: Path) -> tuple[Supervisor, router.Listening]:
    sup = Supervisor(tmp_path / "logs")
    (tmp_path / "logs").mkdir()
    try:
        return sup, router.start_router(sup, (), timeout_s=WAIT_S)
    except BaseException:
        sup.stop_in_order([], sup.names(), grace_s=1.0)
        raise


def test_a_taken_default_port_makes_the_launch_take_a_free_one_and_say_so(
    tmp_path: Path, held_port: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    taken = f"tcp/127.0.0.1:{held_port}"
    monkeypatch.setattr(router, "DEFAULT_CONNECT", taken)
    sup, listening = _start(tmp_path)
    try:
        assert listening.endpoint != taken and listening.endpoint.startswith("tcp/127.0.0.1:")
        assert listening.instead_of_default == f"{taken} is taken"
        assert sup.names() == [router.ROUTER] and sup.children[router.ROUTER].proc.poll() is None
    finally:
        sup.stop_in_order([], sup.names(), grace_s=1.0)


def test_a_default_port_taken_as_the_router_starts_is_given_up_for_a_free_one(
    tmp_path: Path, held_port: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    # another launch binds 7447 between this one's look and its router's bind: the router
    # exits "Address already in use", and a second one listens on a free port instead
    taken = f"tcp/127.0.0.1:{held_port}"
    monkeypatch.setattr(router, "DEFAULT_CONNECT", taken)
    monkeypatch.setattr(router, "port_free", lambda endpoint: True)
    sup, listening = _start(tmp_path)
    try:
        assert listening.endpoint != taken
        assert listening.instead_of_default == f"{taken} was taken as the router started"
        assert sup.children[router.ROUTER].proc.poll() is None  # the second router
    finally:
        sup.stop_in_order([], sup.names(), grace_s=1.0)


@pytest.mark.slow
@pytest.mark.netns
def test_a_plain_launch_and_a_plain_monitor_meet(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with lab_or_skip() as lab:
        ns = lab.namespace("d")  # its own loopback: 7447 is free there
        try:
            with Tidelink("monitor", "--json", netns=ns) as mon:
                mon.wait_for(r"no router at .* yet; waiting", WAIT_S, stdout=True)
                launch = ["launch", SMALL, "--runtime", "lockstep", "--out", str(out)]
                launch += ["--set", "run.max_time_s=6", "--no-plot"]
                with Tidelink(*launch, netns=ns) as run:
                    assert run.wait(WAIT_S) == judged_exit(out), run.stderr
                assert mon.wait(WAIT_S) == 0, mon.stderr  # the run it watched has ended
        finally:
            kill_recorded(out / "pids.json")
    assert f"router listening on {DEFAULT_CONNECT}\n" in run.stderr + "\n"
    assert "watch it live from another terminal: tidelink monitor (or tidelink foxglove)" in (
        run.stderr
    )
    events = [json.loads(x) for x in mon.out if x.startswith("{")]
    ends = [e for e in events if e.get("event") == "end"]
    assert len(ends) == 1 and ends[0]["text"].endswith("max_time"), events[-3:]
