"""`tidelink graph`: a mission's declared dataflow, from a scenario or from a live run."""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from services.cli.flags import Subparsers, certs_args, command, connect_arg, scenario_args
from services.cli.graph_render import to_dot, to_png, to_text

if TYPE_CHECKING:
    from common.runtime.model.dataflow import DataflowDescription


def _from_scenario(a: argparse.Namespace) -> list[tuple[str, DataflowDescription]]:
    from common.config.scenario import load_scenario
    from common.runtime.model.mission import load_mission

    scenario, _ = load_scenario(a.scenario, a.overrides, a.seed)
    title = f"dataflow of {scenario.run.name}/{scenario.run.vehicle} ({a.scenario})"
    return [(title, load_mission(scenario).dataflow.describe())]


def _from_live_run(a: argparse.Namespace) -> list[tuple[str, DataflowDescription]]:
    from common.bus import Bus, Keys
    from common.config.bus import client_config
    from common.runtime.model.dataflow import read_description

    selector = Keys.matching(a.run, a.vehicle).dataflow
    cfg = client_config(a.connect, a.certs)
    with Bus(cfg, Keys(a.run or "any", a.vehicle or "any"), identity=a.identity) as bus:
        replies = bus.query(selector, timeout_s=a.timeout)
    if not replies:
        raise RuntimeError(f"no running mission answered on {selector} via {a.connect}")
    return [
        (f"dataflow of live run {f.key}", read_description(json.loads(f.payload)))
        for f in sorted(replies)
    ]


def cmd_graph(a: argparse.Namespace) -> int:
    """print a mission's dataflow (services, streams, types, links)"""
    if (a.scenario is None) == (a.connect is None):
        raise ValueError("graph: give a SCENARIO file, or --connect ENDPOINT for a live run")
    graphs = _from_scenario(a) if a.scenario is not None else _from_live_run(a)
    for n, (title, described) in enumerate(graphs):
        if a.json:
            print(json.dumps({"title": title, **described}, sort_keys=True))
        else:
            print(to_text(described, title))
        suffix = f"-{n}" if len(graphs) > 1 else ""
        if a.dot is not None:
            path = a.dot.with_name(a.dot.stem + suffix + a.dot.suffix)
            path.write_text(to_dot(described, title))
            print(f"dot: {path}", file=sys.stderr)
        if a.png is not None:
            path = a.png.with_name(a.png.stem + suffix + a.png.suffix)
            print(f"png: {to_png(described, title, path)}", file=sys.stderr)
    return 0


def register(sub: Subparsers) -> None:
    """Add graph to the tidelink parser."""
    g = command(sub, "graph", cmd_graph)
    scenario_args(g, required=False)  # no SCENARIO when --connect asks a live run
    connect_arg(g, help="ask the live run on this router instead")
    g.add_argument("--run", default=None, help="with --connect: the run id (default: any)")
    g.add_argument("--vehicle", default=None, help="with --connect: the vehicle id (default: any)")
    g.add_argument("--timeout", type=float, default=3.0, help="with --connect: seconds to wait")
    certs_args(g, identity="monitor")
    g.add_argument("--dot", type=Path, default=None, help="also write Graphviz DOT to this file")
    g.add_argument("--png", type=Path, default=None, help="also draw the graph to this PNG")
    g.add_argument("--json", action="store_true", help="print the declaration as JSON")
