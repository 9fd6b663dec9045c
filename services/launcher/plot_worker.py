"""A process that imports matplotlib while the mission runs, then draws the run's plot.

Importing matplotlib costs `tidelink run` ~0.3 s of CPU, a fifth of its wall time outside
the mission. PlotWorker starts this module as a child process when the run begins: on the
second core it imports matplotlib during the mission, then waits on its stdin (no polling)
for one job, a pickled sketch (sketch.py: plain data) and the PNG's path; it draws, saves
and exits 0. End of input without a job (the run failed, was interrupted, or the parent
died) ends it quietly. If it fails in any way (cannot start, crashes, hangs), the parent
draws the sketch itself, so the plot is never lost to the helper; an error writing the PNG
is then raised by the parent's own attempt, as without a worker.
"""

from __future__ import annotations

import logging
import os
import pickle
import subprocess
import sys
from pathlib import Path
from types import TracebackType

from services.launcher.sketch import Call, draw_sketch, save_figure

log = logging.getLogger(__name__)

# the worker's draw takes ~0.3 s; one that has not finished in this long is stuck
DRAW_TIMEOUT_S = 60.0


class PlotWorker:
    """The child process (started by the constructor), ended by `draw` or on leaving `with`."""

    def __init__(self) -> None:
        try:
            # its own session: a terminal's Ctrl-C reaches only us, and we end it
            self._proc: subprocess.Popen[bytes] | None = subprocess.Popen(
                [sys.executable, "-m", __name__],
                stdin=subprocess.PIPE,
                stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE,
                start_new_session=True,
            )
        except OSError as exc:
            log.debug("no plot worker (%s): the plot is drawn in this process", exc)
            self._proc = None

    def __enter__(self) -> PlotWorker:
        """The worker, ended on leaving (close)."""
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        """End the worker if no draw used it (the run failed or was interrupted)."""
        self.close()

    def draw(self, calls: list[Call], path: Path) -> Path:
        """Draw the sketch's calls into `path` (PNG) in the worker, or here if it cannot;
        return the path. The worker is used up either way."""
        proc, self._proc = self._proc, None
        if proc is not None:
            job = pickle.dumps((calls, path), protocol=pickle.HIGHEST_PROTOCOL)
            try:
                _, err = proc.communicate(job, timeout=DRAW_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                proc.kill()
                _, err = proc.communicate()
            if proc.returncode == 0:
                return path
            why = err.decode(errors="replace").strip().splitlines()[-1:] or ["no message"]
            log.debug("plot worker ended %s (%s): drawing here", proc.returncode, why[0])
        return save_figure(draw_sketch(calls), path)

    def close(self) -> None:
        """End an unused worker (it holds nothing worth waiting for) and reap it."""
        proc, self._proc = self._proc, None
        if proc is not None:
            proc.kill()
            proc.communicate()


def main() -> int:
    """The worker: import matplotlib, then draw the one job read from stdin (none: exit 0)."""
    # imported before the job arrives: this is the work done while the mission runs
    import matplotlib.backends.backend_agg  # noqa: F401
    import matplotlib.figure  # noqa: F401
    import matplotlib.patches  # noqa: F401

    try:
        calls, path = pickle.load(sys.stdin.buffer)
    except EOFError:
        return 0  # no plot after all
    save_figure(draw_sketch(calls), path)
    return 0


if __name__ == "__main__":
    code = main()
    # the PNG is written and closed, and the parent waits for this exit: skip the interpreter's
    # teardown of matplotlib and numpy (~0.15 s), as a multiprocessing child does
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)
