"""Write the generated reference pages, docs/cli.md and docs/config.md; --check: exit 1 if stale."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from services.cli import build_parser
from services.cli.reference_docs import pages

ROOT = Path(__file__).resolve().parents[1]


def main(check: bool) -> int:
    stale = []
    for path, text in pages(ROOT, build_parser()).items():
        name = path.relative_to(ROOT).as_posix()
        current = path.read_text() if path.exists() else None
        if current == text:
            continue
        if check:
            stale.append(name)
            continue
        path.write_text(text)
        print(f"wrote {name}")
    for name in stale:
        print(f"{name} is stale: run python scripts/gen_docs.py", file=sys.stderr)
    return 1 if stale else 0


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--check", action="store_true", help="only check; exit 1 naming stale files")
    sys.exit(main(p.parse_args().check))
