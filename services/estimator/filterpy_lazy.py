"""filterpy's Kalman filters without the sub-packages they never use loaded at import.

filterpy's package __init__ imports every sub-package. Two of them cost a service's start:
- `filterpy.stats`: every filterpy.kalman module imports `logpdf` from it, which imports
  scipy.stats (0.4-1 s of a process's start: half a service's import time) and calls it once
  at import. The filters use it only for their likelihood properties, which the estimator
  never reads;
- `filterpy.discrete_bayes` imports scipy.ndimage (60-90 ms); `gh`, `hinfinity`, `leastsq`,
  `memory` and `monte_carlo` cost ~0.3-0.5 ms each. The estimator uses none of them.
So before filterpy is imported, each is registered as a stand-in (`_stand_in`) that runs the
real package's own __init__ into itself on the first use of a name it does not hold, and is
the real module from then on (`import filterpy.discrete_bayes` then `.predict` works as
ever). Import the filters from here; filterpy itself is untouched.
"""

from __future__ import annotations

import importlib.util
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

# filterpy's sub-packages loaded on first use (filterpy.kalman and filterpy.common are used)
LAZY = ("stats", "discrete_bayes", "gh", "hinfinity", "leastsq", "memory", "monte_carlo")


def _logpdf(*args: Any, **kwargs: Any) -> Any:
    """filterpy.stats.logpdf, loading filterpy.stats (and scipy.stats) on the first call:
    filterpy.kalman imports the name at its own import, so the stand-in holds it."""
    return _load(sys.modules["filterpy.stats"]).logpdf(*args, **kwargs)


def _load(module: types.ModuleType) -> types.ModuleType:
    """A stand-in made the real package: its __init__ run in the stand-in's namespace (once;
    again on a later use if it raised)."""
    spec = module.__spec__
    if "__getattr__" not in vars(module) or spec is None or spec.loader is None:
        return module  # loaded already
    attribute = vars(module).pop("__getattr__")  # names missing from now on are missing
    try:
        spec.loader.exec_module(module)
    except BaseException:
        module.__getattr__ = attribute  # type: ignore[method-assign]
        raise
    return module


def _stand_in(root: Path, name: str, **held: Callable[..., Any]) -> None:
    """Register `filterpy.<name>` (its directory under root) as a stand-in holding `held`,
    unless the real one is imported already."""
    full = f"filterpy.{name}"
    if full in sys.modules:
        return
    here = root / name
    spec = importlib.util.spec_from_file_location(
        full, here / "__init__.py", submodule_search_locations=[str(here)]
    )
    if spec is None:
        return  # not a package here: filterpy's own import says what is wrong
    module = importlib.util.module_from_spec(spec)  # __path__ set: submodules import as usual
    # a module's own attributes answer without loading it: a scan of sys.modules (hypothesis
    # reads every module's __file__) loaded scipy.stats in every test process
    vars(module).update(held)

    def attribute(attr: str) -> Any:
        # a star import asks __all__ and then reads the namespace: load it first
        if attr.startswith("__") and attr.endswith("__") and attr != "__all__":
            raise AttributeError(attr)
        return getattr(_load(module), attr)

    module.__getattr__ = attribute  # type: ignore[method-assign]
    sys.modules[full] = module


def _stand_ins() -> None:
    """Register every LAZY stand-in before filterpy's __init__ imports the sub-packages."""
    spec = importlib.util.find_spec("filterpy")
    if spec is None or spec.origin is None:
        return  # filterpy missing: the import below says so
    root = Path(spec.origin).parent
    for name in LAZY:
        _stand_in(root, name, **({"logpdf": _logpdf} if name == "stats" else {}))


_stand_ins()

from filterpy.common import Q_discrete_white_noise  # noqa: E402
from filterpy.kalman import (  # noqa: E402
    ExtendedKalmanFilter,
    KalmanFilter,
    MerweScaledSigmaPoints,
    UnscentedKalmanFilter,
)

__all__ = [
    "ExtendedKalmanFilter",
    "KalmanFilter",
    "MerweScaledSigmaPoints",
    "Q_discrete_white_noise",
    "UnscentedKalmanFilter",
]
