"""The experiment file: a base scenario, grid axes of scenario overrides, and seeds.

An experiment TOML file is parsed by the central config loader (common.config.loader.build),
so every error names the file and the key path. Example::

    name = "delay"
    scenario = "../default.toml"          # relative to this file
    seeds = 3
    controllers = ["nurbs", "backstepping", "fuzzy_pid"]
    set = { "run.max_time_s" = 200.0 }    # overrides applied to every cell

    [[axes]]
    name = "delay"
    x_label = "one-way delay (s)"
    [[axes.values]]
    label = "100ms"
    x = 0.1
    set = { "network.default" = { delay_s = 0.1 } }

The grid is the cartesian product of the axes (``controllers`` adds a last axis named
"controller"); every cell runs ``seeds`` times with seeds first_seed, first_seed + 1, ...
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path

from common.config.controller import ControllerKind
from common.config.loader import build, read_toml

# What a `set` entry may hold: the TOML values a scenario key can take, including tables
# (e.g. a whole network profile) and arrays of tables (outages, per-link overrides).
Scalar = bool | int | float | str
Flat = Scalar | tuple[Scalar, ...]
SubTable = dict[str, Flat | dict[str, Flat]]
SetValue = Flat | SubTable | tuple[SubTable, ...]

CONTROLLER_AXIS = "controller"
_NAME = re.compile(r"^[A-Za-z][A-Za-z0-9_]*$")
_KEY = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.[A-Za-z_][A-Za-z0-9_]*)*$")
# columns of results.csv an axis name must not shadow
RESERVED = frozenset(
    {"run_id", "status", "error", "seed", "runtime", "wall_s", "finished_at", "cell", "success"}
)


def _check_set(field_name: str, overrides: dict[str, SetValue]) -> None:
    for key in overrides:
        if not _KEY.match(key):
            raise ValueError(
                f"{field_name}: {key!r} is not a dotted scenario key like 'network.default.delay_s'"
            )


@dataclass(frozen=True, kw_only=True)
class AxisValue:
    """One point of an axis: a label, the scenario overrides it applies, and its plot position."""

    label: str
    set: dict[str, SetValue] = field(default_factory=dict)
    x: float = math.nan  # numeric position on the plots' x axis; absent: categorical

    def __post_init__(self) -> None:
        if not self.label or any(c in self.label for c in ',\n"|'):
            raise ValueError(f'label: {self.label!r} must be non-empty without , " | or newlines')
        _check_set("set", self.set)


@dataclass(frozen=True, kw_only=True)
class Axis:
    """A named grid dimension: a list of values, each a table of scenario overrides."""

    name: str
    values: tuple[AxisValue, ...]
    x_label: str = ""  # plot label of the x axis, e.g. "one-way delay (s)"

    def __post_init__(self) -> None:
        if not _NAME.match(self.name) or self.name in RESERVED:
            raise ValueError(
                f"name: {self.name!r} must be an identifier and not one of "
                f"{', '.join(sorted(RESERVED))}"
            )
        if not self.values:
            raise ValueError("values: an axis needs at least one value")
        labels = [v.label for v in self.values]
        dup = sorted({lab for lab in labels if labels.count(lab) > 1})
        if dup:
            raise ValueError(f"values: label {dup[0]!r} appears twice, expected unique labels")

    @property
    def numeric(self) -> bool:
        """Whether every value has a finite plot position x."""
        return all(math.isfinite(v.x) for v in self.values)


@dataclass(frozen=True, kw_only=True)
class Experiment:
    """A sweep: base scenario, axes (their product is the grid of cells) and seeds."""

    name: str
    scenario: str  # base scenario file, relative to the experiment file
    seeds: int = 3
    first_seed: int = 1
    controllers: tuple[ControllerKind, ...] = ()  # shorthand for an axis "controller"
    set: dict[str, SetValue] = field(default_factory=dict)  # applied to every cell first
    axes: tuple[Axis, ...] = ()
    x_axis: str = ""  # the axis on the plots' x; default: the first that is not "controller"

    def __post_init__(self) -> None:
        if not re.match(r"^[A-Za-z0-9_\-]+$", self.name):
            raise ValueError(f"name: {self.name!r} must be letters, digits, '_' or '-'")
        if not self.scenario:
            raise ValueError("scenario: the base scenario file is required")
        if not 1 <= self.seeds <= 10_000:
            raise ValueError(f"seeds: {self.seeds} is invalid, expected 1..10000")
        if not 0 <= self.first_seed < 2**62:
            raise ValueError(f"first_seed: {self.first_seed} is invalid, expected >= 0")
        if len(set(self.controllers)) != len(self.controllers):
            raise ValueError("controllers: a controller is listed twice")
        _check_set("set", self.set)
        names = [a.name for a in self.all_axes]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(
                f"axes: axis name {dup[0]!r} is used twice (controllers adds "
                f"an axis {CONTROLLER_AXIS!r})"
            )
        if self.x_axis and self.x_axis not in names:
            raise ValueError(f"x_axis: {self.x_axis!r} is not an axis ({', '.join(names)})")
        _check_conflicts(self.all_axes)

    @property
    def all_axes(self) -> tuple[Axis, ...]:
        """The axes with the `controllers` shorthand expanded into a last axis."""
        if not self.controllers:
            return self.axes
        ctrl = Axis(
            name=CONTROLLER_AXIS,
            x_label="controller",
            values=tuple(AxisValue(label=c, set={"controller.kind": c}) for c in self.controllers),
        )
        return (*self.axes, ctrl)

    @property
    def plot_axis(self) -> str:
        """The axis the plots put on x."""
        if self.x_axis:
            return self.x_axis
        others = [a.name for a in self.all_axes if a.name != CONTROLLER_AXIS]
        if others:
            return others[0]
        return self.all_axes[0].name if self.all_axes else ""

    def n_runs(self) -> int:
        return math.prod(len(a.values) for a in self.all_axes) * self.seeds


def _overlaps(a: str, b: str) -> bool:
    """Whether two dotted keys touch the same scenario value (equal, or one inside the other)."""
    return a == b or a.startswith(b + ".") or b.startswith(a + ".")


def _check_conflicts(axes: tuple[Axis, ...]) -> None:
    """Two axes must not set the same key: the cell's value would depend on axis order."""
    keys = [(ax.name, k) for ax in axes for k in {k for v in ax.values for k in v.set}]
    for i, (ax_a, ka) in enumerate(keys):
        for ax_b, kb in keys[i + 1 :]:
            if ax_a != ax_b and _overlaps(ka, kb):
                raise ValueError(
                    f"axes: axes {ax_a!r} and {ax_b!r} both set {ka!r}/{kb!r}, "
                    "expected each scenario key on one axis only"
                )


def load_experiment(path: str | Path) -> Experiment:
    """Read and validate an experiment file; its scenario path is resolved against the file."""
    p = Path(path)
    exp = build(Experiment, read_toml(p), file=str(p))
    scenario = Path(exp.scenario)
    if not scenario.is_absolute():
        scenario = (p.parent / scenario).resolve()
    return dataclasses.replace(exp, scenario=str(scenario))
