"""A pytest plugin for keeping the suite lean: the machine's CPU each test used.

    PYTHONPATH=tests python -m pytest -p helpers.cpu_use ...   (one test at a time: no -n)

Each test's share is the machine's busy CPU time (/proc/stat, every process) between its
setup and its teardown, so run it alone on an otherwise idle machine; the costliest tests
are printed at the end.
"""

from __future__ import annotations

from pathlib import Path

import pytest

_USED: dict[str, float] = {}


def _busy_s() -> float:
    fields = [int(x) for x in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    return (sum(fields) - fields[3] - fields[4]) / 100.0  # jiffies of 10 ms, idle + iowait out


@pytest.hookimpl(wrapper=True)
def pytest_runtest_protocol(item: pytest.Item, nextitem: pytest.Item | None) -> object:
    start = _busy_s()
    try:
        return (yield)
    finally:
        _USED[item.nodeid] = _busy_s() - start


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    total = sum(_USED.values())
    terminalreporter.write_sep("=", f"CPU used: {total:.1f} core-s in all")
    for nodeid, used in sorted(_USED.items(), key=lambda kv: -kv[1])[:60]:
        terminalreporter.write_line(f"{used:7.2f} core-s  {nodeid}")
