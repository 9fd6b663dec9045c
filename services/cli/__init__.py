"""The `tidelink` command line: one module per group of sub-commands, registered here."""

from __future__ import annotations

import argparse
import difflib
import gc
import logging
import platform
import sys
from typing import Any

from common.config.errors import ConfigValueError
from common.config.loader import ConfigError
from services.cli import (
    chaos_commands,
    core_commands,
    foxglove_commands,
    graph_commands,
    launch_commands,
    monitor_commands,
    record_commands,
    security_commands,
    sweep_commands,
)

# Each module exposes register(subparsers); add a tool's module here to give it a sub-command.
COMMAND_MODULES = (
    core_commands,
    graph_commands,
    launch_commands,
    monitor_commands,
    record_commands,
    sweep_commands,
    foxglove_commands,
    security_commands,
    chaos_commands,
)


class _Version(argparse.Action):
    """--version: the versions that decide who can talk to whom (looked up only when asked,
    so that every other command starts without importing the wire format)."""

    def __init__(self, option_strings: list[str], dest: str, **kwargs: Any) -> None:
        super().__init__(option_strings, dest, nargs=0, help="print the version and exit")

    def __call__(self, parser: argparse.ArgumentParser, *args: Any, **kwargs: Any) -> None:
        print(version_text())
        parser.exit()


def version_text() -> str:
    """`tidelink X (wire format vN; eclipse-zenoh Z; Python P)`."""
    from importlib import metadata

    from common.messages import WIRE_VERSION

    def installed(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "not installed"

    return (
        f"tidelink {installed('tidelink')} (wire format v{WIRE_VERSION}; eclipse-zenoh "
        f"{installed('eclipse-zenoh')}; Python {platform.python_version()})"
    )


class TidelinkParser(argparse.ArgumentParser):
    """The top-level parser; it knows its sub-commands' parsers, to suggest one for a typo."""

    commands: dict[str, argparse.ArgumentParser]  # set by build_parser


def build_parser() -> TidelinkParser:
    p = TidelinkParser(prog="tidelink", description="Networked AUV path control over Zenoh.")
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    p.add_argument("--version", action=_Version)
    sub = p.add_subparsers(dest="cmd", required=True)
    for module in COMMAND_MODULES:
        module.register(sub)
    p.commands = dict(sub.choices)
    return p


def suggest_command(p: TidelinkParser, argv: list[str]) -> None:
    """Exit 2 with "did you mean" when the sub-command is none of the parser's: the first
    argument that is no option (the top-level options take no value)."""
    given = next((x for x in argv if not x.startswith("-")), None)
    if given is None or given in p.commands:
        return
    names = list(p.commands)
    close = [n for n in names if n.startswith(given)] or difflib.get_close_matches(
        given, names, n=3, cutoff=0.6
    )
    hint = f"did you mean {' or '.join(repr(n) for n in close[:3])}? " if close else ""
    p.error(f"unknown command {given!r}; {hint}`tidelink --help` lists them all")


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `tidelink` console script (argv None: this process's command line,
    which ends when the command returns)."""
    code = run_command(sys.argv[1:] if argv is None else argv)
    if argv is None:
        # the process is about to end: leave every object to the OS rather than to the
        # interpreter's last collections over all of numpy's and scipy's (~0.1 s of a
        # `tidelink run`'s wall, ~10 ms left with this)
        gc.freeze()
    return code


def run_command(args: list[str]) -> int:
    """Parse the command line `args`, run its command and return the exit code."""
    p = build_parser()
    suggest_command(p, args)
    a = p.parse_args(args)
    logging.basicConfig(
        level=logging.DEBUG if a.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
        stream=sys.stderr,
    )
    try:
        return int(a.func(a))
    except (ConfigError, ConfigValueError) as exc:  # a file's, or a flag's value
        print(f"tidelink: config error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("tidelink: interrupted", file=sys.stderr)
        return 130
    except (RuntimeError, ValueError, TimeoutError, OSError) as exc:
        print(f"tidelink: error: {exc}", file=sys.stderr)
        return 1
