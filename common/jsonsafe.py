"""JSON-safe values: what a metrics file, a sweep's record or a monitor's line can hold; and
the type of JSON that no schema here describes."""

from __future__ import annotations

import math
from typing import Any, TypeAlias

# A JSON value as json.loads gives it: data whose shape no type here declares, such as a
# scenario's raw tables (TOML read as is, before the config dataclasses; the builder refuses
# the dates TOML also has, so a scenario's raw data is JSON) or a Foxglove layout file. Where
# the shape is known, a TypedDict or a msgspec struct says it instead.
JsonValue: TypeAlias = str | int | float | bool | None | list["JsonValue"] | dict[str, "JsonValue"]
JsonObject: TypeAlias = dict[str, JsonValue]


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
