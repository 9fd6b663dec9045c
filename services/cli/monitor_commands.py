"""`tidelink monitor`: watch live runs on a router, as a terminal dashboard or JSON lines."""

from __future__ import annotations

import argparse
import sys

from services.cli.flags import Subparsers, command, watch_fields, watcher_args


def cmd_monitor(a: argparse.Namespace) -> int:
    """watch live runs on a router: vehicle, services, streams, links, alarms

    Find the runs on a router by their liveliness tokens and watch them (all runs unless --run
    is given, side by side). Exits 0 when the watched runs end, unless --follow."""
    from common.runtime.processes.signals import stop_on_signals
    from services.monitor.monitor import Monitor, MonitorOptions, MonitorView
    from services.monitor.views import DashboardView, JsonLinesView

    opts = MonitorOptions(
        **watch_fields(a),
        follow=a.follow,
        rate_hz=a.rate,
        every_frame=a.all,
        update_s=a.every,
        stale_s=a.stale,
        no_wait=a.no_wait,
    )
    with stop_on_signals() as stop:
        view: MonitorView = JsonLinesView(sys.stdout) if a.json else DashboardView()
        return Monitor(opts, view, stop).run()


def register(sub: Subparsers) -> None:
    """Add monitor to the tidelink parser."""
    m = command(sub, "monitor", cmd_monitor)
    watcher_args(m, runs="every run", vehicles="every vehicle")
    m.add_argument("--json", action="store_true", help="one JSON object per event/update")
    m.add_argument(
        "--follow", action="store_true", help="keep watching across a run's end and new runs"
    )
    m.add_argument(
        "--rate",
        type=float,
        default=None,
        metavar="HZ",
        help="thin links: poll only, HZ times a second (default: once per update, plus every "
        "message of the event streams: status, path, end); the vehicle's state each poll, "
        "every stream every 2 s",
    )
    m.add_argument(
        "--all",
        action="store_true",
        help="receive every message of every stream instead of polling (scripts that want "
        "them all; costs the monitor's host CPU in proportion)",
    )
    m.add_argument(
        "--every", type=float, default=0.5, metavar="S", help="seconds between updates (0.5)"
    )
    m.add_argument(
        "--stale", type=float, default=2.0, metavar="S", help="alarm when a stream is older (2)"
    )
    m.add_argument(
        "--no-wait", action="store_true", help="exit 2 at once if there is no run to watch"
    )
