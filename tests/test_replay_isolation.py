"""A replay never touches a live run (issue 61): it plays under a fresh name when its run is
live on the router, is refused when told to play into it (--as), puts nothing on any control
key, and says so and exits 1 when the router's access control drops its puts. Real
`tidelink router` and `tidelink replay` processes; the "live run" is a session of this test
holding the run's clock role and tokens, as a launcher does."""

from __future__ import annotations

import json
import threading
import time
from pathlib import Path

import pytest
from helpers.launch_proc import REPO, Tidelink

from common.bus import CLOCK, Bus, Keys, RawFrame
from common.bus.watcher import WatchedFrame, Watcher
from common.config.bus import client_config
from common.config.scenario import load_scenario
from common.messages import RunEnd, TruthState, encode
from common.runtime.distributed.acl import access_control, run_grants
from common.runtime.distributed.claim import claim
from common.runtime.model.mission import load_mission
from common.runtime.processes.children import free_port, wait_for_endpoint
from services.recording.layout import stream_types
from services.recording.writer import RunInfo, RunWriter

pytestmark = pytest.mark.slow

SMALL = REPO / "configs" / "experiments" / "scenarios" / "small.toml"
WAIT_S = 60.0
FRAMES = 40


def _recording(path: Path) -> None:
    """A recording of run small/auv1: FRAMES truths 10 ms apart, then its RunEnd."""
    scenario, raw = load_scenario(SMALL)
    info = RunInfo(run="small", vehicle="auv1", scenario_raw=raw, recorder="test")
    w = RunWriter(path, info, stream_types(scenario))
    t0 = time.time()
    w.alive("vehicle", True, t0)
    for i in range(1, FRAMES + 1):
        msg = TruthState(
            stamp=i * 0.1, x=float(i), y=0.0, theta=0.0, v=1.0, w=0.0, source="vehicle", seq=i
        )
        w.frame("vehicle", "truth", encode(msg), None, t0 + i * 0.01)
    end = RunEnd(stamp=FRAMES * 0.1, reason="goal", ticks=FRAMES, source=CLOCK, seq=1)
    w.frame(CLOCK, "end", encode(end), None, t0 + FRAMES * 0.01 + 0.01)
    w.close()


def test_a_replay_plays_beside_a_live_run_never_into_it(tmp_path: Path) -> None:
    mcap = tmp_path / "run.mcap"
    _recording(mcap)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    control: list[RawFrame] = []
    lock = threading.Lock()

    def heard(f: RawFrame) -> None:
        with lock:
            control.append(f)

    with Tidelink("router", "--listen", endpoint):
        assert wait_for_endpoint(endpoint, WAIT_S)
        live = Keys("small", "auv1")
        cfg = client_config(endpoint, None)
        with Bus(cfg, live) as run, Bus(cfg, Keys("w", "w")) as watch:
            claim(run, live, CLOCK)  # the live run's clock, as a launcher holds it
            run.declare_alive(CLOCK)
            run.declare_alive("vehicle")
            run.subscribe_raw("tidelink/*/*/*/*", heard)  # every control key of every run
            watcher = Watcher(watch, "small-replay", "auv1")
            watcher.start()
            with Tidelink("replay", str(mcap), "--connect", endpoint, "--speed", "4") as r:
                assert r.wait(WAIT_S) == 0, r.stderr
            assert "run small/auv1 is live on the router" in r.stderr
            assert "as small-replay" in r.stderr
            truths = []
            deadline = time.monotonic() + 5.0
            while len(truths) < FRAMES and time.monotonic() < deadline:
                ev = watcher.get(0.2)
                if isinstance(ev, WatchedFrame) and ev.stream == "truth":
                    truths.append(ev)
            # told to play into the live run: refused, before anything is put
            with Tidelink("replay", str(mcap), "--connect", endpoint, "--as", "small") as r2:
                assert r2.wait(WAIT_S) == 1, r2.stderr
            assert "replaying into it would falsify it: refused" in r2.stderr
    assert len(truths) == FRAMES  # watchers see the replay, under its own name
    with lock:
        assert control == []  # and no control key of any run carried a replayed frame


def test_a_replay_the_routers_access_control_denies_says_so(certs: Path, tmp_path: Path) -> None:
    mcap = tmp_path / "run.mcap"
    _recording(mcap)
    scenario, _ = load_scenario(SMALL)
    keys = Keys("small", "auv1")
    acl = tmp_path / "acl.json"
    acl.write_text(json.dumps(access_control(run_grants(load_mission(scenario).dataflow, keys))))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    secured = ["--connect", endpoint, "--certs", str(certs)]
    with Tidelink("router", "--listen", endpoint, "--certs", str(certs), "--acl", str(acl)):
        assert wait_for_endpoint(endpoint, WAIT_S)
        # the run the access control is for: the launcher identity may put its watch copies
        with Tidelink("replay", str(mcap), *secured, "--speed", "8") as allowed:
            assert allowed.wait(WAIT_S) == 0, allowed.stderr
        # another run's keys: every put would be dropped, and it says so
        with Tidelink("replay", str(mcap), *secured, "--as", "other") as denied:
            assert denied.wait(WAIT_S) == 1, denied.stderr
    assert f"published {FRAMES} frames to watchers as run small" in allowed.stderr
    assert "its access control denies identity 'launcher'" in denied.stderr
    assert "published" not in denied.stderr
