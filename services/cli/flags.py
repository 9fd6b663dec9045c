"""The flags several sub-commands share, each declared once here.

As zenoh-python's examples add the Zenoh flags every program shares with one helper, the
endpoints are `-e/--connect` and `-l/--listen` wherever a command has them (the short flags
of Zenoh's own tools); what differs between commands (one endpoint or repeatable, required
or defaulted) is a keyword, the flag itself is not re-declared. The other shared groups:
a scenario and its overrides, the certificates, --insecure, --no-plot, --budget, how a run
is reported (--json, --verbose), and the watchers' run selection. Every sub-command is added
by `command`, and its function's docstring is what its --help says.
"""

from __future__ import annotations

import argparse
import inspect
import math
from collections.abc import Callable
from pathlib import Path
from typing import TypeAlias, TypedDict

from common.config.bus import DEFAULT_CONNECT

# argparse's containers: a parser, or a group of mutually exclusive flags inside one
Flags = argparse._ActionsContainer
# what a command module's register() adds its sub-commands to (not subscriptable at run time)
Subparsers: TypeAlias = "argparse._SubParsersAction[argparse.ArgumentParser]"


def command(
    sub: Subparsers, name: str, func: Callable[[argparse.Namespace], int]
) -> argparse.ArgumentParser:
    """Sub-command `name`, which runs `func` on its arguments. The docstring of `func` is
    what --help says of it: its first paragraph the command's line in `tidelink --help`, the
    rest (if any) the description its own --help gives above its flags."""
    first, _, rest = inspect.cleandoc(func.__doc__ or "").partition("\n\n")
    p = sub.add_parser(name, help=" ".join(first.split()) or None, description=rest or None)
    p.set_defaults(func=func)
    return p


class EndpointFlag:
    """An endpoint flag: `names` (short and long) with metavar ENDPOINT; how a command takes
    it (`repeat`: given any number of times; a default; required) is said where it adds it."""

    def __init__(self, *names: str) -> None:
        self.names = names

    def __call__(
        self,
        p: Flags,
        *,
        help: str,
        default: str | list[str] | None = None,
        required: bool = False,
        repeat: bool = False,
    ) -> None:
        if repeat:
            p.add_argument(
                *self.names,
                action="append",
                default=[] if default is None else default,
                required=required,
                metavar="ENDPOINT",
                help=help,
            )
        else:
            p.add_argument(
                *self.names, default=default, required=required, metavar="ENDPOINT", help=help
            )


# -e/--connect ENDPOINT: a router to join
connect_arg = EndpointFlag("-e", "--connect")
# -l/--listen ENDPOINT: where a router listens
listen_arg = EndpointFlag("-l", "--listen")


def watcher_args(p: argparse.ArgumentParser, *, runs: str, vehicles: str) -> None:
    """-e/--connect, --run, --vehicle and the credentials of the tools that watch live runs
    (monitor, foxglove, record): the run's router, and which run and vehicle to watch;
    `runs` and `vehicles` say which a command takes without --run and --vehicle."""
    connect_arg(
        p,
        default=DEFAULT_CONNECT,
        help=f"the run's router (default {DEFAULT_CONNECT}, where `tidelink launch` listens "
        "when that port is free; otherwise the launch prints its own)",
    )
    p.add_argument("--run", default=None, help=f"only this run id (default: {runs})")
    p.add_argument("--vehicle", default=None, help=f"only this vehicle id (default: {vehicles})")
    certs_args(p, identity="monitor")


class WatchFields(TypedDict):
    """The fields of a WatchTarget (common/config/bus.py) that watcher_args read."""

    connect: str
    certs: str | None
    identity: str
    run: str | None
    vehicle: str | None


def watch_fields(a: argparse.Namespace) -> WatchFields:
    """What watcher_args read, as the fields of a WatchTarget (common/config/bus.py)."""
    return WatchFields(
        connect=a.connect, certs=a.certs, identity=a.identity, run=a.run, vehicle=a.vehicle
    )


def certs_args(p: argparse.ArgumentParser, *, identity: str | None) -> None:
    """--certs DIR (mutual TLS with the certificates `tidelink certs` made) and, for tools
    that are not a service of the run, --identity: whose certificate to present."""
    p.add_argument(
        "--certs",
        type=_certs_dir,
        default=None,
        metavar="DIR",
        help="secure the bus: mutual TLS with the certificates in DIR (`tidelink certs`); "
        "tcp/ endpoints are then served as tls/ on the same address",
    )
    if identity is not None:
        p.add_argument(
            "--identity",
            default=identity,
            metavar="NAME",
            help=f"with --certs: whose certificate to present (default {identity})",
        )


def _certs_dir(text: str) -> str:
    """An absolute path: child processes and other working directories see the same DIR."""
    return str(Path(text).expanduser().resolve())


def insecure_arg(p: argparse.ArgumentParser) -> None:
    """--insecure: listening beyond loopback without --certs is allowed (with a warning)."""
    p.add_argument(
        "--insecure",
        action="store_true",
        help="allow a --listen endpoint beyond loopback without --certs (prints a warning)",
    )


def scenario_args(p: argparse.ArgumentParser, *, required: bool = True) -> None:
    """SCENARIO, --set KEY=VALUE (repeatable) and --seed N."""
    p.add_argument(
        "scenario",
        type=Path,
        nargs=None if required else "?",
        default=None,
        help="scenario TOML file, e.g. configs/default.toml",
    )
    p.add_argument(
        "--set",
        dest="overrides",
        action="append",
        default=[],
        metavar="KEY=VALUE",
        help="override a scenario key, e.g. --set network.default.loss_p=0.2 (repeatable)",
    )
    p.add_argument("--seed", type=int, default=None, help="override run.seed")


def no_plot_arg(p: argparse.ArgumentParser) -> None:
    """--no-plot: a command that runs a mission draws it into DIR/run.png unless told not to."""
    p.add_argument("--no-plot", action="store_true", help="do not write DIR/run.png")


def details_arg(p: argparse.ArgumentParser) -> None:
    """--verbose: a command that runs a mission prints its short verdict unless asked for
    every metric (the top-level -v/--verbose, before the sub-command, is debug logging)."""
    p.add_argument(
        "--verbose",
        dest="all_metrics",
        action="store_true",
        help="print every scalar metric after the verdict (DIR/metrics.json has them all)",
    )


def report_args(p: argparse.ArgumentParser) -> None:
    """--json and --verbose: how a command that runs a mission reports it at the end."""
    p.add_argument("--json", action="store_true", help="print the metrics as one JSON object")
    details_arg(p)


def host_args(p: argparse.ArgumentParser) -> None:
    """--budget, --certs and --insecure: what a command that runs a mission on this host (its
    router among its processes) is allowed, and how its bus is secured."""
    budget_arg(p)
    certs_args(p, identity=None)
    insecure_arg(p)


def budget_arg(p: argparse.ArgumentParser) -> None:
    """--budget FACTOR: the work budget `tidelink check` enforces, scaled (a bigger machine)."""
    p.add_argument(
        "--budget",
        type=positive("factor"),
        default=1.0,
        metavar="FACTOR",
        help="allow FACTOR times every work budget a scenario is checked against (the planner "
        "grid's memory, the record's memory, the run's wall time), e.g. 4 on a bigger machine",
    )


def positive(what: str) -> Callable[[str], float]:
    """An argparse type: a finite number > 0, refused as "'TEXT' is not a WHAT > 0"."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            value = math.nan
        if not (math.isfinite(value) and value > 0.0):
            raise argparse.ArgumentTypeError(f"{text!r} is not a {what} > 0")
        return value

    return parse
