"""The suite's own scheduling: tests of one module-scoped fixture share one xdist worker, and
so do the tests marked exclusive, one after another."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

TESTS = Path(__file__).resolve().parent

MODULE = """
import os
import pytest

@pytest.fixture(scope="module")
def costly():
    with open("computed.txt", "a") as fh:
        fh.write(os.environ.get("PYTEST_XDIST_WORKER", "none") + "\\n")

def test_one(costly): pass
def test_two(costly): pass
def test_three(costly): pass
def test_other(): pass

@pytest.mark.exclusive
@pytest.mark.parametrize("n", range(4))
def test_alone(n):
    with open("alone.txt", "a") as fh:
        fh.write(os.environ.get("PYTEST_XDIST_WORKER", "none") + "\\n")
"""


def test_a_module_fixture_is_computed_once_on_two_workers(tmp_path: Path) -> None:
    # scripts/test's phases run `-n 2 --dist loadgroup`: were the fixture's tests spread over
    # both workers, a fixture that is a whole launch would run twice (pytest 9.2 broke this
    # silently: pytest-xdist#1386, hence the pin in pyproject.toml)
    shutil.copy(TESTS / "conftest.py", tmp_path / "conftest.py")  # it imports tests/helpers
    (tmp_path / "test_shared.py").write_text(MODULE)
    r = subprocess.run(
        [sys.executable, "-m", "pytest", "-n", "2", "--dist", "loadgroup", "-p",
         "no:cacheprovider", "-q", "-o", "addopts=", "-o", "markers=exclusive",
         "test_shared.py"],
        cwd=tmp_path, capture_output=True, text=True, timeout=120,
        env=dict(os.environ, PYTHONPATH=f"{TESTS}{os.pathsep}{os.environ.get('PYTHONPATH', '')}"),
    )  # fmt: skip
    assert r.returncode == 0, r.stdout + r.stderr
    assert "8 passed" in r.stdout, r.stdout
    computed = (tmp_path / "computed.txt").read_text().split()
    assert len(computed) == 1 and computed[0].startswith("gw"), computed
    alone = (tmp_path / "alone.txt").read_text().split()
    assert len(alone) == 4 and len(set(alone)) == 1 and alone[0].startswith("gw"), alone


def test_every_slow_mark_is_spelled_as_scripts_test_looks_for_it() -> None:
    # scripts/test gives its wall-clock phase only the modules that say `pytest.mark.slow`,
    # its background run those that say `pytest.mark.background`: a test marked any other
    # way (an alias, a bare `mark.slow`) would never run
    for path in sorted(TESTS.glob("test_*.py")):
        if path.name == Path(__file__).name:
            continue  # this check names the marks in strings
        text = path.read_text()
        for mark in ("slow", "background"):
            assert text.count(f"mark.{mark}") == text.count(f"pytest.mark.{mark}"), path.name
