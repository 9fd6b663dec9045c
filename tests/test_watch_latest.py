"""The tap's latest queryable answers a poll with what it asks for: the newest frame of each
stream newer than `?after=N`, of the `;streams=` named only, never of the `;except=` named
(what `monitor --rate` relies on).
Real Zenoh: the tap on a router session, the watcher on a client session."""

from __future__ import annotations

from helpers.samples import one_of_each

from common.bus import Bus, Keys
from common.bus.tap import WatchTap
from common.bus.watcher import Watcher
from common.config.bus import BusConfig
from common.messages import StateEstimate, TruthState, VehicleStatus, decode
from common.runtime.processes.children import free_port

SAMPLES = {type(m): m for m in one_of_each()}
STREAMS = {
    ("vehicle", "truth"): SAMPLES[TruthState],
    ("vehicle", "status"): SAMPLES[VehicleStatus],
    ("estimator", "state"): SAMPLES[StateEstimate],
}


def _wait_for(tap: WatchTap, count: int, timeout_s: float = 10.0) -> None:
    assert tap.caught_up(count, timeout_s=timeout_s), f"the tap got {tap.count} of {count} frames"


def test_a_poll_gets_the_named_streams_newer_than_its_mark() -> None:
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    keys = Keys("latest", "auv1")
    with Bus(BusConfig(mode="router", listen=(endpoint,)), keys) as run:
        tap = WatchTap(run, keys, {"run": {"name": "latest"}})
        pubs = {k: run.publisher(*k) for k in STREAMS}
        for k, msg in STREAMS.items():  # tap counts 1, 2, 3
            pubs[k].put(msg)
        _wait_for(tap, 3)
        with Bus(BusConfig(mode="client", connect=(endpoint,)), Keys("w", "w")) as bus:
            w = Watcher(bus)
            every = w.latest(keys)
            assert [(f.service, f.stream) for f in every] == list(STREAMS)  # by tap count
            assert [type(decode(f.payload)) for f in every] == list(map(type, STREAMS.values()))
            only = w.latest(keys, streams=["vehicle/truth", "estimator/state"])
            assert [(f.service, f.stream) for f in only] == [
                ("vehicle", "truth"),
                ("estimator", "state"),
            ]
            but = w.latest(keys, excluding=["vehicle/truth", "estimator/state"])
            assert [(f.service, f.stream) for f in but] == [("vehicle", "status")]
            pubs[("vehicle", "truth")].put(SAMPLES[TruthState])  # tap count 4
            _wait_for(tap, 4)
            newer = w.latest(keys, after=3, streams=["vehicle/truth", "vehicle/status"])
            assert [(f.service, f.stream, f.n) for f in newer] == [("vehicle", "truth", 4)]
            assert w.latest(keys, after=4) == []
            assert w.latest(keys, streams=["vehicle/nothing"]) == []
            tap.end("goal", 12.5, 0)  # the run's end is a stream a poll can name too
            (end,) = w.latest(keys, after=4, streams=["runtime/end"])
            assert (end.service, end.stream, end.n) == ("runtime", "end", 5)
