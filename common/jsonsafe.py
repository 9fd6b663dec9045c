"""JSON-safe values: what a metrics file, a sweep's record or a monitor's line can hold."""

from __future__ import annotations

import math
from typing import Any


def json_safe(v: Any) -> Any:
    """`v` with every non-finite float replaced by None (JSON has no NaN or infinity), through
    nested dicts, lists and tuples (tuples become lists)."""
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, dict):
        return {k: json_safe(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [json_safe(x) for x in v]
    return v
