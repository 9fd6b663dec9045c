"""A stand-in service module for tests of forked service processes (tests/test_forked.py)."""

from __future__ import annotations

import signal
import sys


def main(argv: list[str]) -> int:
    """`exit N`: print a line and exit N; `block`: print a line, then wait for a signal."""
    print(f"child argv {argv}", flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    if argv[0] == "exit":
        return int(argv[1])
    signal.pause()
    return 0
