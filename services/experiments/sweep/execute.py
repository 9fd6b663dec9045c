"""Where the runs of a sweep execute: here, a local process pool, or a Dask cluster."""

from __future__ import annotations

import logging
import multiprocessing
import os
import threading
import time
import traceback
import uuid
from collections.abc import Callable, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed

from services.experiments.sweep.grid import RunSpec
from services.experiments.sweep.worker import RunOutcome, execute_run

log = logging.getLogger("tidelink.sweep")

OnDone = Callable[[RunSpec, RunOutcome], None]


def _lost(spec: RunSpec, exc: BaseException) -> RunOutcome:
    """The outcome of a run whose worker died or could not be reached."""
    text = "".join(traceback.format_exception(exc))
    return RunOutcome(
        run_id=spec.run_id,
        status="error",
        error=f"worker failed: {type(exc).__name__}: {exc}\n{text}",
    )


def run_serial(specs: Sequence[RunSpec], on_done: OnDone) -> None:
    """One run after another in this process (jobs = 1)."""
    for spec in specs:
        on_done(spec, execute_run(spec))


def _exit_with(parent_pid: int, poll_s: float = 0.5) -> None:
    """Pool initializer: the worker ends itself once the sweep that started it is gone."""

    # A killed sweep (SIGKILL, SIGTERM, a closed terminal) cannot shut its pool down; its
    # workers would run on, unseen, for minutes, taking the cores from the next sweep.
    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(1)

    threading.Thread(target=watch, name="exit-with-sweep", daemon=True).start()


def run_pool(specs: Sequence[RunSpec], on_done: OnDone, jobs: int) -> None:
    """A local process pool; each outcome is handed to on_done as soon as it finishes."""
    # spawn, not fork: the parent may hold threads (progress bar) that fork would not copy
    ctx = multiprocessing.get_context("spawn")
    pool = ProcessPoolExecutor(
        max_workers=max(1, min(jobs, len(specs))),
        mp_context=ctx,
        initializer=_exit_with,
        initargs=(os.getpid(),),
    )
    try:
        futures: dict[Future[RunOutcome], RunSpec] = {pool.submit(execute_run, s): s for s in specs}
        for fut in as_completed(futures):
            spec = futures[fut]
            try:
                outcome = fut.result()
            except Exception as exc:  # noqa: BLE001 - a dead worker fails its run, not the sweep
                outcome = _lost(spec, exc)
            on_done(spec, outcome)
    except BaseException:
        pool.shutdown(wait=False, cancel_futures=True)
        raise
    pool.shutdown(wait=True)


def run_dask(specs: Sequence[RunSpec], on_done: OnDone, scheduler: str) -> None:
    """Submit every run to an existing Dask distributed scheduler, collect as they finish.

    The workers need tidelink importable (the same installation); each run is one task.
    """
    from distributed import Client
    from distributed import as_completed as dask_completed

    tag = uuid.uuid4().hex[:8]  # task keys stay unique if two sweeps share a cluster
    with Client(scheduler, timeout=30) as client:
        log.info(
            "dask scheduler %s: %d workers",
            scheduler,
            len(client.scheduler_info().get("workers", {})),
        )
        futures = {
            client.submit(execute_run, s, key=f"tidelink-{s.run_id}-{tag}", pure=False): s
            for s in specs
        }
        try:
            for fut in dask_completed(list(futures)):
                spec = futures[fut]
                try:
                    outcome = fut.result()
                except Exception as exc:  # noqa: BLE001 - a lost worker fails its run only
                    outcome = _lost(spec, exc)
                on_done(spec, outcome)
        except BaseException:
            client.cancel(list(futures))
            raise


def run_all(specs: Sequence[RunSpec], on_done: OnDone, *, jobs: int, scheduler: str = "") -> None:
    """Dispatch to Dask (scheduler given), a process pool (jobs > 1) or this process."""
    if not specs:
        return
    if scheduler:
        run_dask(specs, on_done, scheduler)
    elif jobs > 1 and len(specs) > 1:
        run_pool(specs, on_done, jobs)
    else:
        run_serial(specs, on_done)
