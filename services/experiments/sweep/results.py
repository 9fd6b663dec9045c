"""results.csv: one row per finished run, appended durably so an interrupted sweep loses nothing.

Each row is written with a single write() and fsync'ed before the next run is reported. A
sweep killed mid-write leaves at most a torn last line (no trailing newline), which is cut off
when the file is opened again, so that run is simply redone. A row bringing a column the
header lacks (a metric appearing for the first time) rewrites the file atomically with the
wider header.
"""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path

from common.runtime.metrics_record import Row, Scalar

# first columns, in this order; grid parameters follow, then every metric sorted by name
LEAD = ("run_id", "status", "seed")
TAIL_FACTS = ("runtime", "wall_s", "finished_at", "error")


def _cell(v: Scalar | None) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v) if math.isfinite(v) else ""
    return str(v).replace("\r", " ").replace("\n", " | ")


class ResultsFile:
    """An append-only CSV of run rows with a header that only grows."""

    def __init__(self, path: Path, grid_columns: tuple[str, ...] = ()) -> None:
        self.path = path
        self.grid_columns = grid_columns
        self.header: list[str] = []
        self.rows: list[dict[str, str]] = []
        self._load()

    def _load(self) -> None:
        if not self.path.exists():
            return
        data = self.path.read_bytes()
        if data and not data.endswith(b"\n"):  # a torn last row from a killed sweep
            data = data[: data.rfind(b"\n") + 1]
            with self.path.open("r+b") as fh:
                fh.truncate(len(data))
                os.fsync(fh.fileno())
        reader = csv.DictReader(io.StringIO(data.decode("utf-8")))
        self.header = list(reader.fieldnames or [])
        self.rows = [r for r in reader if r.get("run_id")]

    def ids(self, status: str | None = None) -> set[str]:
        """Run ids already recorded (optionally only those with this status)."""
        return {r["run_id"] for r in self.rows if status is None or r.get("status") == status}

    def _columns(self, row: Row) -> list[str]:
        have = set(self.header)
        new = [k for k in row if k not in have]
        if not new:
            return self.header
        lead = [*LEAD, *self.grid_columns, *TAIL_FACTS]
        known = set(lead)
        rest = sorted((have | set(new)) - known)
        return [c for c in lead if c in have or c in row] + rest

    def append(self, row: Row) -> None:
        """Add one row durably (write + flush + fsync); widen the header if needed."""
        text = {k: _cell(v) for k, v in row.items()}
        columns = self._columns(row)
        if columns != self.header:
            self.header = columns
            self.rows.append(text)
            self._rewrite()
            return
        buf = io.StringIO()
        csv.DictWriter(buf, fieldnames=self.header, lineterminator="\n").writerow(text)
        fd = os.open(self.path, os.O_WRONLY | os.O_APPEND)
        try:
            os.write(fd, buf.getvalue().encode("utf-8"))  # one write: a row is whole or torn
            os.fsync(fd)
        finally:
            os.close(fd)
        self.rows.append(text)

    def drop(self, ids: set[str]) -> None:
        """Forget rows (e.g. failed runs to retry); rewrites the file atomically."""
        self.rows = [r for r in self.rows if r["run_id"] not in ids]
        if self.header:
            self._rewrite()

    def _rewrite(self) -> None:
        buf = io.StringIO()
        w = csv.DictWriter(buf, fieldnames=self.header, lineterminator="\n", restval="")
        w.writeheader()
        for r in self.rows:
            w.writerow(r)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        tmp = self.path.with_suffix(".csv.tmp")
        with tmp.open("w", encoding="utf-8") as fh:
            fh.write(buf.getvalue())
            fh.flush()
            os.fsync(fh.fileno())
        tmp.replace(self.path)
        dfd = os.open(self.path.parent, os.O_RDONLY)  # make the rename itself durable
        try:
            os.fsync(dfd)
        finally:
            os.close(dfd)


def as_number(text: str | None) -> float:
    """A CSV cell as a number: True/False as 1/0, empty or text as nan."""
    if text is None or text == "":
        return math.nan
    if text in ("True", "False"):
        return 1.0 if text == "True" else 0.0
    try:
        return float(text)
    except ValueError:
        return math.nan
