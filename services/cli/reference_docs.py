"""The generated reference pages: docs/cli.md (every `--help`) and docs/config.md (every key)."""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from common.config.reference import markdown as config_tables

GENERATOR = "python scripts/gen_docs.py"
HELP_COLUMNS = "100"  # argparse wraps to the terminal's width: fix it, so the page is the same

CONFIG_INTRO = """\
# Scenario reference

A scenario is a TOML file. Every section is optional and every key takes the default below;
`tidelink check SCENARIO` validates one (exit 0, or 2 with `file: key.path: what is wrong`).
A top-level `extends = "other.toml"` (relative to the file) starts from another scenario and
merges this file's tables over it, key by key (an array such as `world.circles` is replaced
whole). Unknown keys, wrong types, out-of-range or inconsistent values are errors naming the
file and the key.

The commands that load a scenario (`check`, `run`, `launch`, `service`, `graph`, `acl`,
`chaos`) take `--set KEY=VALUE` to override a key: a dotted key path and a TOML value, e.g.
`--set network.default.loss_p=0.2` or `--set 'controller.kind="fuzzy_pid"'` (bare words are
read as strings too); an experiment file overrides keys the same way
([experiments.md](experiments.md)).

Units are in the key names: `_m` metres, `_s` seconds, `_mps` metres per second, `_mps2`
metres per second squared, `_rad` radians, `_rps` radians per second, `_ps` per second, `_hz`
hertz, `_khz` kilohertz, `_bps` bits per second, `_db` decibels, `_kg` kilograms, `_p` a
probability. Positions are in the scenario's metres, x east, y north.

Network links are named `source/stream->receiver`; a `[[network.links]]` entry matches an
exact link, `source/stream->*` or `*->receiver` and replaces the default profile for it. In a
fleet, see [fleets.md](fleets.md) for how link names select vehicles.

`run.mission` names a registered mission, never code: `"auv"` (the AUV mission, the default),
or a name the environment variable `TIDELINK_MISSIONS=name=module:Class[,...]` adds (the tests
add `testloop=tests.helpers.testloop:TestLoop`, the runtime self-test loop). Their registered
targets (the older spelling `"services.mission:AuvMission"`) are accepted too; any other value
is a config error listing the registered missions, and nothing is imported.

## Ocean current

`[world.current]` is the water every vehicle of a run moves in (the same for every vehicle of
a fleet; `common/world/current.py`), a pure function of position, time and `run.seed`:

    c(x, y, t) = f(t) (U + S s / (2 W)) d  +  sum of Gaussian eddies  +  b(t)

- `speed_mps` U flowing towards `direction_deg` (d = (cos, sin) of it: counter-clockwise from
  east, 90 flows north); `direction = "seeded"` draws the direction uniformly in [0, 360) from
  `run.seed` instead;
- `shear_mps` S: the along-flow speed is U + S/2 on the area's left edge (looking downstream)
  and U - S/2 on its right edge, varying linearly across the flow (s the distance from the
  area's centre line, W the area's half-width across the flow);
- `tidal_period_s` P, `tidal_amplitude` A, `tidal_phase_rad`: f(t) = 1 + A sin(2 pi t / P +
  phase) scales the uniform and shear part (P = 0: no tide);
- `[[world.current.eddies]]`: Gaussian vortices, tangential speed V (r/R) exp((1 - r^2/R^2)/2)
  with `speed_mps` V (> 0 counter-clockwise) peaking at `radius_m` R from (`x_m`, `y_m`);
- `sigma_mps`, `tau_s`, `update_s`: gusts, a Gauss-Markov process per axis, uniform in space
  (stationary std sigma, correlation time tau, exact samples every update_s, linear between).

Every part is off by default (still water). `vehicle.current` of older scenarios is an error
that says so.

## Work budget

Every command that runs a scenario (`check`, `run`, `launch`, and `sweep` for each cell)
first estimates the work of one run from the config and refuses one over its budget, before
anything is allocated (`common/config/budget.py`; the estimate is in `common/config/work.py`,
its unit costs measured by `scripts/bench budget`):

- **planner grid**: (width / `planner.resolution_m`) × (height / `planner.resolution_m`)
  cells of `world.area`, at a replan's peak 240 B a cell (Dijkstra, 8 neighbours; 392 B with
  16; A* 1052 B and 1844 B); budget 1 GiB, i.e. 4.47e6 cells (e.g. 1 km × 1 km at 0.5 m);
- **record**: every message a run publishes is kept in memory (~1 KiB each, plus ~60 B per
  entry of a command's sequence: 6 KiB a command at the default 10 s horizon) until its
  metrics are computed: the services' rates × `run.max_time_s`; budget 1 GiB (about 2 h of
  mission at the default rates, 3 h with `controller.sequence.horizon_s = 0`);
- **wall time**: every service period, every vehicle RK4 step (`run.max_time_s` /
  `vehicle.dt_internal_s`) and every estimator prediction sub-step (at most
  `estimator.max_predict_dt_s`) at their measured costs, and `run.max_time_s` /
  `runtime.time_scale` for a realtime run; budget 1 h.

The error (exit 2) names the key that makes the work large (the one furthest from its
default), e.g. `planner.resolution_m: planner.resolution_m=0.001 over a 100 m × 40 m area is
a 4e+09-cell cost map (~894 GiB at a replan's peak, ...); the budget is 4.47e+06 cells (~1
GiB): coarsen the resolution or shrink world.area`. `--budget FACTOR` scales every budget (a
bigger machine; a sweep with `--jobs N` runs N such runs at once).

## Keys
"""


def _header(title: str) -> str:
    return f"<!-- generated by `{GENERATOR}`: do not edit by hand -->\n\n{title}"


@contextmanager
def _fixed_terminal() -> Iterator[None]:
    """argparse reads the width from COLUMNS; pin it (and no colour) while rendering."""
    keys = ("COLUMNS", "NO_COLOR", "PYTHON_COLORS")
    saved = {k: os.environ.get(k) for k in keys}
    os.environ.update(COLUMNS=HELP_COLUMNS, NO_COLOR="1", PYTHON_COLORS="0")
    try:
        yield
    finally:
        for k, v in saved.items():
            if v is None:
                os.environ.pop(k, None)
            else:
                os.environ[k] = v


def _commands(parser: argparse.ArgumentParser) -> Iterator[argparse.ArgumentParser]:
    """`parser` and every sub-command under it, depth first, in the order they were added."""
    yield parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in dict.fromkeys(action.choices.values()):  # aliases name a parser twice
                yield from _commands(sub)


def cli_markdown(parser: argparse.ArgumentParser) -> str:
    """docs/cli.md: the `--help` of `parser` and of every sub-command, each in a fenced block."""
    parts = [
        _header("# Command-line reference\n"),
        "Every `tidelink` command's `--help`, as the program prints it. The user guide is the",
        "[README](../README.md); the scenario keys are in [config.md](config.md).\n",
    ]
    with _fixed_terminal():
        for p in _commands(parser):
            parts += [f"## `{p.prog}`\n", "```text", p.format_help().rstrip(), "```\n"]
    return "\n".join(parts)


def config_markdown() -> str:
    """docs/config.md: what a scenario file is, its work budget, then every key's table."""
    return _header(CONFIG_INTRO) + "\n" + config_tables().rstrip() + "\n"


def pages(root: Path, parser: argparse.ArgumentParser) -> dict[Path, str]:
    """Each generated file under the repository `root` with the text it must hold."""
    return {
        root / "docs" / "cli.md": cli_markdown(parser),
        root / "docs" / "config.md": config_markdown(),
    }
