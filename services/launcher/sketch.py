"""A figure as the list of axes calls that draw it, made without matplotlib and drawn later.

plot.py works out what a run's figure shows (numpy only) into a Sketch; draw_sketch makes
the matplotlib figure from it. The split lets `tidelink run` hand a sketch, plain picklable
data, to a process that imported matplotlib while the mission ran (plot_worker.py), and keeps
matplotlib's ~0.3 s import off the run's critical path.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # matplotlib is imported when a sketch is drawn, not with this module
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

FIGSIZE_IN = (11.0, 5.5)
DPI = 110  # the saved PNG's (1.2k x 0.65k pixels once cropped)

# the Axes methods a sketch records (anything else is a typo, raised at once)
AXES_CALLS = frozenset(
    {
        "add_patch", "annotate", "legend", "plot", "quiver", "scatter",
        "set_aspect", "set_title", "set_xlabel", "set_xlim", "set_ylabel", "set_ylim",
    }
)  # fmt: skip

Call = tuple[str, tuple[Any, ...], dict[str, Any]]  # (Axes method, args, kwargs)


@dataclass(frozen=True)
class Shape:
    """A matplotlib.patches class by name with its arguments, made when the sketch is drawn."""

    kind: str  # "Circle", "Polygon", "Rectangle"
    args: tuple[Any, ...]
    kwargs: dict[str, Any]

    def make(self) -> Patch:
        """The patch itself (imports matplotlib)."""
        from matplotlib import patches

        made: Patch = getattr(patches, self.kind)(*self.args, **self.kwargs)
        return made


def shape(kind: str, *args: Any, **kwargs: Any) -> Shape:
    """Shape(kind, args, kwargs), written like the patch's own constructor call."""
    return Shape(kind, args, kwargs)


@dataclass
class Sketch:
    """One Axes' calls, in order (an Axes stand-in: `sketch.plot(...)` records the call)."""

    calls: list[Call] = field(default_factory=list)

    def __getattr__(self, name: str) -> Any:
        """The recorder of Axes method `name` (AttributeError for one not in AXES_CALLS)."""
        if name not in AXES_CALLS:
            raise AttributeError(name)

        def record(*args: Any, **kwargs: Any) -> None:
            """Keep the call, to be made on the Axes when the sketch is drawn."""
            self.calls.append((name, args, kwargs))

        return record


def draw_sketch(calls: list[Call]) -> Figure:
    """The figure the calls draw on one Axes (Agg canvas: no display needed), laid out."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    fig = Figure(figsize=FIGSIZE_IN)
    FigureCanvasAgg(fig)
    ax = fig.add_subplot()
    for name, args, kwargs in calls:
        made = tuple(a.make() if isinstance(a, Shape) else a for a in args)
        getattr(ax, name)(*made, **kwargs)
    fig.tight_layout()
    return fig


def save_figure(fig: Figure, path: Path) -> Path:
    """Write the figure to `path` (PNG, cropped to what it shows) and return it."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    return path
