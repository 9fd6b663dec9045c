"""Markdown builders every report is composed of: a table, a section, the document.

A block is a paragraph (one string) or some lines; blocks are set apart by one blank line,
and an empty block ("" or no lines) is left out, so an optional part of a report is a block
that may be empty.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence

Block = str | Sequence[str]


def table(head: Sequence[str], rows: Iterable[Sequence[str]]) -> list[str]:
    """A pipe table: the header, its rule, one line per row (cells already text)."""
    return [_row(head), "|" + "---|" * len(head), *(_row(r) for r in rows)]


def _row(cells: Sequence[str]) -> str:
    return "| " + " | ".join(cells) + " |"


def blocks(*parts: Block) -> list[str]:
    """The blocks' lines, one blank line between two blocks; empty blocks left out."""
    out: list[str] = []
    for part in parts:
        lines = ([part] if part else []) if isinstance(part, str) else list(part)
        if lines:
            out += [*([""] if out else []), *lines]
    return out


def section(title: str, *parts: Block, level: int = 2) -> list[str]:
    """A heading of `level` and its blocks (a section is a block, so sections nest)."""
    return blocks(f"{'#' * level} {title}", *parts)


def document(*parts: Block) -> str:
    """The text of a Markdown file: its blocks, and a blank line at the end."""
    return "\n".join(blocks(*parts)) + "\n\n"
