"""`tidelink run`'s plot worker (services/launcher/plot_worker.py) draws the same PNG as this
process would; if it has died the plot is drawn here all the same; an unused one is ended."""

from __future__ import annotations

from pathlib import Path

import pytest
from helpers.launch_proc import REPO

from common.config.scenario import load_scenario
from common.runtime.model.record import Record
from services.launcher.plot import run_sketch
from services.launcher.plot_worker import PlotWorker
from services.launcher.sketch import Call, draw_sketch, save_figure

DEFAULT = REPO / "configs" / "default.toml"


def _calls() -> list[Call]:
    """The default scenario's figure with an empty record: its area, obstacles, start, goal."""
    scenario, _ = load_scenario(DEFAULT)
    return run_sketch(Record(), scenario, title="worker").calls


def test_the_worker_draws_the_png_this_process_would(tmp_path: Path) -> None:
    here = save_figure(draw_sketch(_calls()), tmp_path / "here.png")
    with PlotWorker() as worker:
        there = worker.draw(_calls(), tmp_path / "out" / "there.png")
    assert there == tmp_path / "out" / "there.png"
    assert there.read_bytes() == here.read_bytes()


def test_a_dead_worker_leaves_the_plot_to_this_process(tmp_path: Path) -> None:
    with PlotWorker() as worker:
        proc = worker._proc
        assert proc is not None
        proc.kill()
        proc.wait()
        drawn = worker.draw(_calls(), tmp_path / "run.png")
    assert drawn.stat().st_size > 0


def test_an_unused_worker_is_ended_on_leaving() -> None:
    with PlotWorker() as worker:
        proc = worker._proc
    assert proc is not None and proc.returncode is not None


def test_a_png_the_worker_cannot_write_is_an_oserror_here(tmp_path: Path) -> None:
    blocked = tmp_path / "a-file"
    blocked.write_text("not a folder")  # the PNG's folder cannot be made
    with PlotWorker() as worker, pytest.raises(OSError):
        worker.draw(_calls(), blocked / "run.png")
