"""services/experiments is three packages with imports running one way: reproduction and
netreport on the sweep engine, never back, never on each other; and what another package
imports from one of them is in that package's INTERFACE (its `__init__.py`)."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXPERIMENTS = "services.experiments"
PACKAGES = ("sweep", "reproduction", "netreport")
# which experiment packages each may import
MAY_IMPORT = {"sweep": set(), "reproduction": {"sweep"}, "netreport": {"sweep"}}


def _imports(path: Path) -> list[tuple[str, list[str]]]:
    """(module, names) of every `from services.experiments.X.Y import ...` in a file."""
    tree = ast.parse(path.read_text(), str(path))
    return [
        (n.module, [a.name for a in n.names])
        for n in ast.walk(tree)
        if isinstance(n, ast.ImportFrom) and n.module and n.module.startswith(EXPERIMENTS + ".")
    ]


def _package(module: str) -> str:
    return module.split(".")[2]


def _production_files() -> list[Path]:
    return [
        p for top in ("services", "common", "scripts") for p in sorted((ROOT / top).rglob("*.py"))
    ]


@pytest.mark.parametrize("package", PACKAGES)
def test_a_package_imports_only_the_packages_beneath_it(package: str) -> None:
    bad = [
        f"{p.relative_to(ROOT)}: {module}"
        for p in sorted((ROOT / "services" / "experiments" / package).rglob("*.py"))
        for module, _ in _imports(p)
        if _package(module) != package and _package(module) not in MAY_IMPORT[package]
    ]
    assert not bad, "imports running back up or across:\n" + "\n".join(bad)


def test_other_packages_import_only_an_interface() -> None:
    interfaces = {
        pkg: importlib.import_module(f"{EXPERIMENTS}.{pkg}").INTERFACE for pkg in PACKAGES
    }
    bad = []
    for p in _production_files():
        rel = p.relative_to(ROOT)
        for module, names in _imports(p):
            pkg = _package(module)
            if rel.parts[:3] == ("services", "experiments", pkg):
                continue  # a package's own modules import one another freely
            allowed = interfaces[pkg].get(module.split(".")[3], ())
            bad += [f"{rel}: {module}.{n}" for n in names if n not in allowed]
    assert not bad, "not in the package's INTERFACE:\n" + "\n".join(bad)


@pytest.mark.parametrize("package", PACKAGES)
def test_an_interface_names_what_its_modules_define(package: str) -> None:
    interface = importlib.import_module(f"{EXPERIMENTS}.{package}").INTERFACE
    for module, names in interface.items():
        defined = vars(importlib.import_module(f"{EXPERIMENTS}.{package}.{module}"))
        assert not [n for n in names if n not in defined], f"{package}.{module}"
