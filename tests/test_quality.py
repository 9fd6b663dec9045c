"""Linters as tests: ruff and mypy (as pyproject.toml configures them) are clean; docstrings."""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
BIN = Path(sys.executable).parent  # the venv's bin: ruff and mypy are installed beside python


def _run(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(BIN / args[0]), *args[1:]],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )


def test_ruff_is_clean() -> None:
    res = _run("ruff", "check", ".")
    print(res.stdout, res.stderr)
    assert res.returncode == 0, f"ruff check . failed:\n{res.stdout}\n{res.stderr}"


@pytest.mark.heavy  # ~15 s of a cold cache
def test_mypy_is_clean() -> None:
    res = _run("mypy")  # packages and options from [tool.mypy]
    print(res.stdout, res.stderr)
    assert res.returncode == 0, f"mypy failed:\n{res.stdout}\n{res.stderr}"


MODULES = sorted(
    p.relative_to(REPO).as_posix()
    for pkg in ("common", "services")
    for p in (REPO / pkg).rglob("*.py")
)


def test_there_are_modules_to_check() -> None:
    assert "common/messages/codec.py" in MODULES
    assert "common/bus/bus.py" in MODULES


@pytest.mark.parametrize("module", MODULES)
def test_every_module_has_a_docstring(module: str) -> None:
    tree = ast.parse((REPO / module).read_text(), filename=module)
    doc = ast.get_docstring(tree)
    assert doc and doc.strip(), f"{module}: no module docstring"
