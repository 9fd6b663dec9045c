"""Regenerate the config reference block in README.md from the config dataclasses."""

from __future__ import annotations

import re
from pathlib import Path

from common.config.reference import markdown

START = "<!-- config-reference:start"
END = "<!-- config-reference:end -->"


def render(readme: str) -> str:
    """README text with the block between the markers replaced by the current reference."""
    pattern = re.compile(re.escape(START) + r"(.*?)-->\n.*?" + re.escape(END), re.S)
    m = pattern.search(readme)
    if m is None:
        raise SystemExit("README.md has no config-reference markers")
    block = f"{START}{m.group(1)}-->\n{markdown()}\n{END}"
    return readme[: m.start()] + block + readme[m.end() :]


if __name__ == "__main__":
    path = Path(__file__).resolve().parents[1] / "README.md"
    path.write_text(render(path.read_text()))
    print(f"updated {path}")
