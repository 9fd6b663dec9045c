"""The recording sub-commands: record (remote), replay and metrics of an MCAP recording."""

from __future__ import annotations

import argparse
import json
import sys
from collections.abc import Callable
from contextlib import closing
from pathlib import Path
from typing import TYPE_CHECKING

from services.cli.core_commands import check_exposure
from services.cli.flags import (
    Subparsers,
    certs_args,
    command,
    connect_arg,
    insecure_arg,
    listen_arg,
    watcher_args,
)

if TYPE_CHECKING:
    from common.bus import Bus
    from common.config.bus import BusConfig
    from common.config.scenario import Scenario
    from common.view import View
    from services.recording.reader import Recording
    from services.recording.remote import RecordOutcome

ROUTER_WAIT_S = 10.0  # replay --connect: how long to wait for the router to accept


def _say(command: str) -> Callable[[str], None]:
    def say(text: str) -> None:
        print(f"tidelink {command}: {text}", file=sys.stderr, flush=True)

    return say


def foxglove_view(scenario: Scenario) -> View:
    """The Foxglove view written beside the raw run, so a recording opens in Foxglove."""
    from services.foxglove.view import FoxgloveView

    return FoxgloveView(scenario)


def _read(path: Path) -> Recording:
    from services.recording.reader import read_recording

    return read_recording(path)  # a cut-short file is logged as a warning, naming it


def cmd_record(a: argparse.Namespace) -> int:
    """record a run on a router to an MCAP file (remotely)"""
    from common.bus import Bus, Keys
    from common.config.bus import client_config
    from common.runtime.processes.children import wait_for_endpoint
    from common.runtime.processes.signals import stop_on_signals
    from services.recording.remote import RemoteRecorder

    say = _say("record")
    with stop_on_signals() as stop:
        if not wait_for_endpoint(a.connect, 0.0):
            say(f"no router at {a.connect} yet; waiting for one (Ctrl-C to stop)")
            while not wait_for_endpoint(a.connect, 0.5):
                if stop.requested:
                    return 130
        cfg = client_config(a.connect, a.certs)
        with Bus(cfg, Keys("record", "record"), identity=a.identity) as bus:
            recorder = RemoteRecorder(
                bus,
                a.out,
                run=a.run,
                vehicle=a.vehicle,
                stop=stop,
                say=say,
                view_for=foxglove_view,
            )
            outcome = recorder.record()
    if outcome is None:
        say("stopped before any run showed up; nothing recorded")
        return 130
    _report(outcome)
    if outcome.ended.startswith("stopped"):
        return 130
    return 0 if outcome.complete else 1


def _report(o: RecordOutcome) -> None:
    total = sum(o.counts.values())
    print(
        f"recorded run {o.run}/{o.vehicle} to {o.path}: {total} frames, "
        f"{o.size_bytes / 1024:.1f} KiB; the run: {o.ended}"
    )
    width = max((len(k) for k in o.counts), default=0)
    for stream, n in sorted(o.counts.items()):
        lost = o.gaps.lost.get(stream, 0)
        print(f"  {stream:<{width}}  {n:>7}" + (f"  ({lost} lost)" if lost else ""))
    if o.gaps.total:
        print(
            f"lost {o.gaps.total} frames (gaps in their seqs, and the run's newest frames "
            "this recorder never got): the run's watch copies are sent DROP, and this recorder "
            "or its link could not keep up, or it was stopped for a while"
        )
    elif o.complete:
        print("lost: none (every stream's seqs are contiguous)")
    if not o.complete:
        after = "" if o.last_stamp_s is None else f" (t={o.last_stamp_s:.2f} s)"
        print(
            f"lost: everything the run sent after the last frame recorded here{after}, "
            "how much is unknown: the run's end never reached this recorder"
        )


def cmd_replay(a: argparse.Namespace) -> int:
    """publish a recorded run again, as a live run"""
    from common.config.bus import client_config
    from common.runtime.processes.children import connectable, free_port, wait_for_endpoint
    from common.runtime.processes.signals import stop_on_signals
    from services.recording.replay import replay

    say = _say("replay")
    rec = _read(a.file)
    if a.connect is not None:
        if not wait_for_endpoint(a.connect, ROUTER_WAIT_S):
            raise TimeoutError(f"no router at {a.connect} after {ROUTER_WAIT_S:g} s")
        cfg = client_config(a.connect, a.certs)
    else:
        listen = a.listen or f"tcp/127.0.0.1:{free_port()}"
        check_exposure([listen], a.certs is not None, a.insecure)
        cfg = client_config(listen, a.certs).router_on((listen,))
        certs = f" --certs {a.certs}" if a.certs else ""
        say(
            f"listening on {cfg.endpoint(listen)}: watch with --connect "
            f"{cfg.endpoint(connectable(listen))}{certs}"
        )
    # _replay_bus hands back an open session (it holds the run's claim): closed, not entered again
    with (
        stop_on_signals() as stop,
        closing(_replay_bus(cfg, rec, a.as_run, a.identity, say)) as bus,
    ):
        outcome = replay(rec, bus, speed=a.speed, stop=stop, lead_s=a.lead, say=say)
    say(
        f"published {outcome.published} frames to watchers as run {outcome.keys.run}; "
        f"end: {outcome.reason}"
    )
    return 130 if outcome.reason == "interrupted" else 0


REPLAY_NAMES = 10  # a replay without --as into a router where its run is live: <run>-replay..9


def _replay_bus(
    cfg: BusConfig, rec: Recording, as_run: str | None, identity: str, say: Callable[[str], None]
) -> Bus:
    """The replay's bus, opened under a run name that is not live on the router: --as RUN, or
    else the recorded run's name, or <run>-replay (then -replay2, ...) when that is live.
    RuntimeError (RoleTaken) when --as names a live run; PermissionError when the router's
    access control drops the replay's puts."""
    from common.bus import Bus, Keys
    from common.runtime.distributed.claim import RoleTaken
    from services.recording.replay import claim_run

    names = [as_run] if as_run else [rec.run, f"{rec.run}-replay"]
    names += [] if as_run else [f"{rec.run}-replay{i}" for i in range(2, REPLAY_NAMES)]
    for name in names:
        bus = Bus(cfg, Keys(name, rec.vehicle), identity=identity)
        bus.__enter__()
        try:
            claim_run(bus)
            return bus
        except RoleTaken as exc:
            bus.close()
            if as_run is not None:
                raise RoleTaken(
                    f"replay --as {as_run}: {exc}; replaying into it would falsify it: refused "
                    "(choose another --as)"
                ) from None
            say(f"{exc}: not replaying into it")
        except BaseException:
            bus.close()
            raise
    raise RoleTaken(f"runs {names[0]} to {names[-1]} are all live on the router")


def cmd_metrics(a: argparse.Namespace) -> int:
    """recompute a run's metrics from its MCAP recording"""
    from services.cli.summary import print_metrics_table
    from services.recording.metrics import NOT_RECOMPUTED, recording_metrics

    metrics = recording_metrics(_read(a.file)).to_json()
    if a.json:
        print(json.dumps(metrics, sort_keys=True, allow_nan=False))
    else:
        print_metrics_table(metrics)
        print(
            f"recomputed from {a.file} (not {', '.join(NOT_RECOMPUTED)}: the launcher's wall "
            "clock, which no recording holds)"
        )
    return 0


def register(sub: Subparsers) -> None:
    """Add record, replay and metrics to the tidelink parser."""
    r = command(sub, "record", cmd_record)
    watcher_args(r, runs="the first run seen", vehicles="any")
    r.add_argument("-o", "--out", type=Path, required=True, help="the MCAP file to write")

    p = command(sub, "replay", cmd_replay)
    p.add_argument("file", type=Path, help="an MCAP recording (launch --record, record)")
    p.add_argument("--speed", type=float, default=1.0, help="time scale (default 1: as recorded)")
    where = p.add_mutually_exclusive_group()
    connect_arg(where, help="publish through this router")
    listen_arg(where, help="be the router, listening here (default: a free port on 127.0.0.1)")
    p.add_argument(
        "--as", dest="as_run", default=None, metavar="RUN", help="replay under this run id"
    )
    p.add_argument(
        "--lead",
        type=float,
        default=1.0,
        help="seconds between declaring the run and its first frame (default 1)",
    )
    certs_args(p, identity="launcher")
    insecure_arg(p)

    m = command(sub, "metrics", cmd_metrics)
    m.add_argument("file", type=Path, help="an MCAP recording (launch --record, record)")
    m.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
