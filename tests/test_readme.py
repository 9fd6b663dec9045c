"""README stays true: the config reference matches the dataclasses, every CLI command is there."""

from __future__ import annotations

import importlib.util
import re
from pathlib import Path

from services.cli import build_parser

ROOT = Path(__file__).resolve().parents[1]


def _updater():  # type: ignore[no-untyped-def]
    spec = importlib.util.spec_from_file_location(
        "update_readme_reference", ROOT / "scripts" / "update_readme_reference.py"
    )
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_config_reference_in_readme_is_current() -> None:
    readme = (ROOT / "README.md").read_text()
    assert _updater().render(readme) == readme, (
        "README's config reference is stale: run python scripts/update_readme_reference.py"
    )


def test_every_cli_command_is_in_the_readme() -> None:
    readme = (ROOT / "README.md").read_text()
    # the sub-commands as argparse's public usage line lists them: {check,run,...}
    m = re.search(r"\{([\w,-]+)\}", build_parser().format_usage())
    assert m
    names = m.group(1).split(",")
    assert "graph" in names and "launch" in names
    for name in names:
        assert f"tidelink {name}" in readme, f"README's CLI reference lacks `tidelink {name}`"


def test_readme_names_the_two_setup_commands_first() -> None:
    readme = (ROOT / "README.md").read_text()
    quick = readme.index("## Quick start")
    assert readme.index("scripts/run", quick) < readme.index("scripts/test", quick)
