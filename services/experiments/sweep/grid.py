"""Expand an experiment into runs: one scenario mapping per (cell, seed), all validated first."""

from __future__ import annotations

import copy
import functools
import hashlib
import itertools
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from common.config.budget import DEFAULT_BUDGET, Budget
from common.config.loader import ConfigError, apply_override, read_scenario_toml
from common.config.scenario import scenario_from_raw
from common.jsonsafe import JsonObject
from common.world.check import check_scenario
from services.experiments.sweep.schema import Experiment, SetValue


@dataclass(frozen=True, kw_only=True)
class RunSpec:
    """One run of a sweep: which cell and seed, and the complete scenario mapping to run."""

    run_id: str
    labels: dict[str, str]  # axis name -> value label, in axis order
    x: float  # position on the plot axis (nan if categorical)
    seed: int
    raw: JsonObject  # the scenario, every override, seed, run name and runtime applied
    log_dir: str = ""  # lockstep: where the service logs go ("" = a temporary folder)
    keep_trajectory: bool = False  # return the truth trajectory with the metrics

    @property
    def cell(self) -> str:
        """The cell as one readable key, e.g. 'delay=100ms|controller=nurbs'."""
        return cell_key(self.labels)


@dataclass(frozen=True, kw_only=True)
class Plan:
    """Every run of an experiment, in grid order, with the file it came from."""

    experiment: Experiment
    file: str
    runtime: str
    runs: tuple[RunSpec, ...] = field(default_factory=tuple)


def cell_key(labels: dict[str, str]) -> str:
    return "|".join(f"{k}={v}" for k, v in labels.items())


def to_raw(value: SetValue | Any) -> Any:
    """A loaded override value back as TOML-shaped data (tuples become lists)."""
    if isinstance(value, tuple | list):
        return [to_raw(v) for v in value]
    if isinstance(value, dict):
        return {k: to_raw(v) for k, v in value.items()}
    return value


def run_id(labels: dict[str, str], overrides: list[tuple[str, Any]], seed: int) -> str:
    """A stable id: the hash of the cell (its labels and overrides) and the seed."""
    blob = json.dumps(
        {"cell": list(labels.items()), "set": overrides, "seed": seed},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def expand(
    exp: Experiment,
    file: str,
    *,
    runtime: str,
    log_root: Path | None = None,
    keep_trajectory: bool = False,
    budget: Budget = DEFAULT_BUDGET,
) -> Plan:
    """Every (cell, seed) with its scenario; raises ConfigError naming the experiment key.

    Each cell is checked as `tidelink check` checks a scenario (geometry, and the work budget
    of one of its runs under this runtime) before any run starts.
    """
    base = read_scenario_toml(exp.scenario)
    axes = exp.all_axes
    where_base = [(f"set.{k}", k, v) for k, v in exp.set.items()]
    runs: list[RunSpec] = []
    for combo in itertools.product(*(list(enumerate(a.values)) for a in axes)):
        labels = {a.name: v.label for a, (_, v) in zip(axes, combo, strict=True)}
        where = list(where_base)
        for ai, (a, (vi, v)) in enumerate(zip(axes, combo, strict=True)):
            origin = f"axes[{ai}].values[{vi}].set" if a in exp.axes else "controllers"
            where += [(f"{origin}.{k}", k, val) for k, val in v.set.items()]
        overrides = [(k, to_raw(val)) for _, k, val in where]
        x = next(
            (v.x for a, (_, v) in zip(axes, combo, strict=True) if a.name == exp.plot_axis),
            float("nan"),
        )
        raw = copy.deepcopy(base)
        for origin, k, val in where:
            try:
                apply_override(raw, k.split("."), to_raw(val))
            except ConfigError as exc:
                raise ConfigError(file, origin, exc.problem) from None
        apply_override(raw, ["runtime", "kind"], runtime)  # the budget depends on it
        for seed in range(exp.first_seed, exp.first_seed + exp.seeds):
            rid = run_id(labels, overrides, seed)
            r = copy.deepcopy(raw)
            apply_override(r, ["run", "seed"], seed)
            apply_override(r, ["run", "name"], f"{exp.name}-{rid}")  # keeps parallel runs apart
            runs.append(
                RunSpec(
                    run_id=rid,
                    labels=labels,
                    x=x,
                    seed=seed,
                    raw=r,
                    log_dir=str(log_root / rid / "logs") if log_root else "",
                    keep_trajectory=keep_trajectory,
                )
            )
        _validate(raw, exp, file, labels, where, budget)
    return Plan(experiment=exp, file=file, runtime=runtime, runs=tuple(runs))


def _validate(
    raw: JsonObject,
    exp: Experiment,
    file: str,
    labels: dict[str, str],
    where: list[tuple[str, str, SetValue]],
    budget: Budget,
) -> None:
    """Build the cell's scenario now, so a bad cell fails the sweep before any run starts."""
    try:
        scenario_from_raw(raw, exp.scenario, check=functools.partial(check_scenario, budget=budget))
    except ConfigError as exc:
        # blame the override that wrote the failing key or a key below it (world.area.x_max_m
        # for a budget error at world.area), if one did (else the base scenario)
        culprit = next((o for o, k, _ in reversed(where) if _nested(exc.key_path, k)), "")
        if not culprit:
            raise
        raise ConfigError(
            file, culprit, f"in cell {cell_key(labels)}: scenario key {exc.key}: {exc.problem}"
        ) from None


def _nested(key_path: tuple[str | int, ...], key: str) -> bool:
    """Whether the dotted `key` lies at, below or above `key_path`."""
    parts = tuple(key.split("."))
    n = min(len(parts), len(key_path))
    return key_path[:n] == parts[:n]
