"""Sweep progress: a rich bar with ETA on a terminal, one plain line per run otherwise."""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import IO, Any


def _hms(s: float) -> str:
    s = max(0, round(s))
    return f"{s // 3600:d}:{s % 3600 // 60:02d}:{s % 60:02d}"


class SweepProgress:
    """Context manager; call `done(text, ok)` once per finished run."""

    def __init__(
        self,
        total: int,
        *,
        title: str = "sweep",
        stream: IO[str] | None = None,
        rich: bool | None = None,
    ) -> None:
        self.total = total
        self.count = 0
        self.errors = 0
        self.title = title
        self.stream = stream or sys.stderr
        self.use_rich = self.stream.isatty() if rich is None else rich
        self._t0 = time.monotonic()
        self._bar: Any = None
        self._task: Any = None

    def __enter__(self) -> SweepProgress:
        self._t0 = time.monotonic()
        if self.use_rich and self.total:
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )

            self._bar = Progress(
                TextColumn("{task.description}"),
                BarColumn(),
                MofNCompleteColumn(),
                TimeElapsedColumn(),
                TextColumn("ETA"),
                TimeRemainingColumn(),
                console=Console(file=self.stream),
            )
            self._bar.start()
            self._task = self._bar.add_task(self.title, total=self.total)
        return self

    def eta_s(self) -> float:
        """Remaining time at the mean pace so far (nan before the first run)."""
        if not self.count:
            return float("nan")
        return (time.monotonic() - self._t0) / self.count * (self.total - self.count)

    def done(self, text: str, ok: bool) -> None:
        self.count += 1
        self.errors += not ok
        if self._bar is not None:
            desc = f"{self.title} ({self.errors} failed)" if self.errors else self.title
            self._bar.update(self._task, advance=1, description=desc)
            if not ok:
                self._bar.console.print(f"[red]failed[/red] {text}")
            return
        eta = self.eta_s()
        print(
            f"[{self.count}/{self.total}] {'ok' if ok else 'ERROR'} {text}"
            f" (elapsed {_hms(time.monotonic() - self._t0)}, eta {_hms(eta)})",
            file=self.stream,
            flush=True,
        )

    def __exit__(
        self, et: type[BaseException] | None, ev: BaseException | None, tb: TracebackType | None
    ) -> None:
        if self._bar is not None:
            self._bar.stop()
