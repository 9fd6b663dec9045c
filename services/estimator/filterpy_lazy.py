"""filterpy's Kalman filters without scipy.stats at import: `filterpy.stats` is loaded on use.

Every filterpy.kalman module imports `logpdf` from filterpy.stats, which imports scipy.stats
(0.4-1 s of a process's start: half a service's import time) and calls it once at import.
The filters use it only for their likelihood properties, which the estimator never reads. So
before filterpy.kalman is imported, `filterpy.stats` is registered as a stand-in whose
`logpdf` (and any other name) loads the real module on its first use. Import the filters
from here; filterpy itself is untouched.
"""

from __future__ import annotations

import importlib
import importlib.util
import sys
import types
from pathlib import Path
from typing import Any


def _real_stats() -> types.ModuleType:
    """filterpy's own statistics module (scipy.stats with it), loaded on the first call."""
    return importlib.import_module("filterpy.stats.stats")


def _logpdf(*args: Any, **kwargs: Any) -> Any:
    return _real_stats().logpdf(*args, **kwargs)


def _stand_in() -> None:
    """Register the `filterpy.stats` stand-in, unless the real one is imported already."""
    if "filterpy.stats" in sys.modules:
        return
    spec = importlib.util.find_spec("filterpy")
    if spec is None or spec.origin is None:
        return  # filterpy missing: the import below says so
    stats = types.ModuleType("filterpy.stats", "filterpy.stats, loaded on first use")
    here = Path(spec.origin).parent / "stats"
    stats.__path__ = [str(here)]  # its submodules import as usual
    # a module's own attributes answer without loading it: a scan of sys.modules (hypothesis
    # reads every module's __file__) loaded scipy.stats in every test process
    stats.__file__ = str(here / "__init__.py")
    stats.logpdf = _logpdf  # type: ignore[attr-defined]
    stats.__getattr__ = _attribute  # type: ignore[method-assign]
    sys.modules["filterpy.stats"] = stats


def _attribute(name: str) -> Any:
    """The stand-in's other names, from the real module; none of a module's dunder names."""
    if name.startswith("__") and name.endswith("__"):
        raise AttributeError(name)
    return getattr(_real_stats(), name)


_stand_in()

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
