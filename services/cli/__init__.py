"""The `tidelink` command line: one module per group of sub-commands, registered here."""

from __future__ import annotations

import argparse
import logging
import sys

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


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="tidelink", description="Networked AUV path control over Zenoh."
    )
    p.add_argument("-v", "--verbose", action="store_true", help="debug logging")
    sub = p.add_subparsers(dest="cmd", required=True)
    for module in COMMAND_MODULES:
        module.register(sub)
    return p


def main(argv: list[str] | None = None) -> int:
    """Entry point of the `tidelink` console script."""
    p = build_parser()
    a = p.parse_args(argv)
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
