"""README and docs stay true: generated pages current, commands runnable, links not broken."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from common.config.errors import ConfigError
from services.cli import build_parser
from services.cli.core_commands import check_exposure
from services.cli.reference_docs import GENERATOR, pages

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"


@pytest.mark.parametrize("name", ["docs/cli.md", "docs/config.md"])
def test_generated_reference_is_current(name: str) -> None:
    expected = pages(ROOT, build_parser())[ROOT / name]
    path = ROOT / name
    assert path.exists() and path.read_text() == expected, f"{name} is stale: run {GENERATOR}"


def _sub_commands() -> list[str]:
    # the sub-commands as argparse's public usage line lists them: {check,run,...}
    m = re.search(r"\{([\w,-]+)\}", build_parser().format_usage())
    assert m
    return m.group(1).split(",")


def test_every_cli_command_is_in_the_readme() -> None:
    readme = README.read_text()
    names = _sub_commands()
    assert "graph" in names and "launch" in names
    for name in names:
        assert f"tidelink {name}" in readme, f"README's CLI tour lacks `tidelink {name}`"


def test_readme_names_the_two_setup_commands_first() -> None:
    readme = README.read_text()
    quick = readme.index("## Quick start")
    assert readme.index("scripts/run", quick) < readme.index("scripts/test", quick)


def _shown_commands(text: str) -> list[str]:
    """Every line of a fenced code block that runs `tidelink` (after an optional `$ `)."""
    lines, fenced = [], False
    for line in text.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        stripped = line.strip().removeprefix("$ ")
        if fenced and stripped.startswith("tidelink "):
            lines.append(stripped)
    return lines


def _argv(line: str) -> list[str]:
    """The words of a shown command: no trailing `# comment`, nothing past a `>` or `|`."""
    argv = shlex.split(line, comments=True)
    for i, word in enumerate(argv):
        if word in (">", "|", "&&", ";"):
            return argv[:i]
    return argv


GUIDES = [README, *sorted((ROOT / "docs").glob("*.md"))]  # the user guides, not the notes


def test_the_readme_shows_commands() -> None:
    assert len(_shown_commands(README.read_text())) >= 10


@pytest.mark.parametrize(
    "doc, line",
    [(doc, line) for doc in GUIDES for line in _shown_commands(doc.read_text())],
    ids=lambda v: v.name if isinstance(v, Path) else v,
)
def test_every_command_the_guides_show_parses(doc: Path, line: str) -> None:
    argv = _argv(line)
    try:
        a = build_parser().parse_args(argv[1:])
    except SystemExit as exc:
        pytest.fail(f"{doc.name} shows a command tidelink refuses ({exc.code}): {line}")
    listen = getattr(a, "listen", None)
    if listen and hasattr(a, "insecure"):  # a router beyond loopback needs --certs or --insecure
        try:
            check_exposure(
                [listen] if isinstance(listen, str) else listen, bool(a.certs), a.insecure
            )
        except ConfigError as exc:
            pytest.fail(f"{doc.name} shows a command tidelink refuses (exit 2, {exc}): {line}")
    for arg in argv[1:]:
        for path in re.findall(r"(?:configs|scripts)/[\w./-]+", arg):
            if path.startswith("configs/") and not path.endswith(".toml"):
                continue
            assert (ROOT / path).exists(), f"{doc.name}'s `{line}` names {path}, which is not there"


DOCS = [*GUIDES, *sorted((ROOT / "docs").glob("*/*.md"))]


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.relative_to(ROOT).as_posix())
def test_local_links_point_at_files(doc: Path) -> None:
    text = doc.read_text()
    for target in re.findall(r"\]\(([^)\s]+)\)", text):
        if re.match(r"[a-z]+:", target) or target.startswith("#"):
            continue  # a web address, a mail address, an anchor in the page
        path = (doc.parent / target.split("#")[0]).resolve()
        assert path.exists(), f"{doc.relative_to(ROOT)} links to {target}, which is not there"
