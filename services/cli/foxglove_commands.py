"""`tidelink foxglove`: serve the runs on a router to the Foxglove app (remote monitoring)."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from pathlib import Path

from services.cli.flags import Subparsers, command, watch_fields, watcher_args


def cmd_foxglove(a: argparse.Namespace) -> int:
    """serve the runs on a router to the Foxglove app (WebSocket)

    Serve the runs on a router to the Foxglove app over WebSocket, to clients of the subprotocol
    foxglove.websocket.v1 (ws-protocol's) or foxglove.sdk.v1 (the SDK's, or its revision
    foxglove.sdk.v1.1)."""
    if a.layout_for is not None:
        return _print_layout(a.layout_for)
    from common.runtime.processes.signals import Shutdown, install_shutdown_handlers
    from services.foxglove.serve import BridgeOptions, serve

    if not a.verbose:
        # what the bridge is doing (serving, waiting, which run) is this command's output
        logging.getLogger("tidelink.foxglove").setLevel(logging.INFO)
    install_shutdown_handlers()
    opts = BridgeOptions(**watch_fields(a), host=a.host, port=a.port)
    try:
        serve(opts)
    except Shutdown as exc:
        logging.getLogger("tidelink.foxglove").info("stopping on %s", exc)
    return 0


def _print_layout(scenario_path: Path) -> int:
    """The Foxglove layout for a scenario's vehicles (a fleet's: every vehicle in each panel)
    on stdout."""
    from common.config.scenario import load_scenario
    from services.foxglove.dashboard import fleet_layout, shipped_layout

    scenario, _ = load_scenario(scenario_path)
    layout = fleet_layout(shipped_layout(), [vid for vid, _ in scenario.members])
    json.dump(layout, sys.stdout, indent=1)
    sys.stdout.write("\n")
    return 0


def register(sub: Subparsers) -> None:
    """Add foxglove to the tidelink parser."""
    f = command(sub, "foxglove", cmd_foxglove)
    watcher_args(f, runs="any, one at a time", vehicles="any")
    f.add_argument("--host", default="127.0.0.1", help="address to serve on (0.0.0.0: all)")
    f.add_argument("--port", type=int, default=8765, help="WebSocket port (default 8765)")
    f.add_argument(
        "--layout-for",
        type=Path,
        metavar="SCENARIO",
        help="print the Foxglove layout for this scenario's vehicles (a fleet: every vehicle "
        "in each panel) and exit; import it in the app with Layouts > Import from file",
    )
