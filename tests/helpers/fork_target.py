"""A stand-in service module for tests of forked service processes (tests/test_forked.py)."""

from __future__ import annotations

import sys

from common.runtime.processes.signals import wait_for_stop


def main(argv: list[str]) -> int:
    """`exit N`: print a line and exit N; `block`: print a line, then wait for a signal."""
    print(f"child argv {argv}", flush=True)
    print("to stderr", file=sys.stderr, flush=True)
    if argv[0] == "exit":
        return int(argv[1])
    wait_for_stop()  # a service's wait: signal.pause() misses a signal landing just before it
    return 0


def fork_from_a_daemon(log_dir: str) -> int:
    """In a daemonic process: start this module the way a run starts a service; its code."""
    from pathlib import Path

    from common.runtime.processes.children import fork

    child = fork("from-daemon", "helpers.fork_target", ["exit", "4"], Path(log_dir))
    return child.proc.wait(timeout=60)


if __name__ == "__main__":  # as a service module is run when spawned: python -m module args
    sys.exit(main(sys.argv[1:]))
