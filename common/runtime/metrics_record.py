"""RunMetrics: a run's metrics.json as one versioned, typed record (the run's facts beside its
mission's own metrics), encoded and decoded here only.

On disk the record is one flat JSON object, as users and docs/metrics.md know it: the
mission's keys, the run's facts (RunFacts) and `schema_version`. A key a run could not measure
is absent (msgspec.UNSET), one it measured as nothing (a non-finite number) is null. A file
of another schema is refused with the version it holds, never half-read: metrics files are
outputs, and re-running is how a new one is made (there is no converter to keep in step).
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Generic, TypeVar

import msgspec

from common.jsonsafe import json_safe

# the layout of metrics.json; raise it when a key changes meaning, type or name. Files written
# before it existed (no schema_version key) are schema 1.
METRICS_SCHEMA = 2
SCHEMA_KEY = "schema_version"

Scalar = bool | int | float | str
# what a CSV row of a run holds: its scalar metrics by name
Row = dict[str, Scalar]

M = TypeVar("M", bound=msgspec.Struct)


class MetricsSchemaError(ValueError):
    """A metrics file of another schema than this tidelink's (or none at all)."""


class InputHealth(msgspec.Struct, kw_only=True, frozen=True):
    """How the services' inputs fared (common/runtime/run.py input_health): inputs rejected
    as implausible, deliveries dropped from a full queue, filters restarted; the totals, and
    by service or link. Facts of every run (RunFacts has these keys)."""

    inputs_rejected: int
    inputs_rejected_by_reason: dict[str, dict[str, int]]
    inputs_dropped: int
    inputs_dropped_by_link: dict[str, int]
    filter_resets: int
    filter_resets_by_service: dict[str, dict[str, int]]


class RunFacts(InputHealth, kw_only=True, frozen=True):
    """What every runtime adds to its mission's metrics (docs/metrics.md "Always present"):
    InputHealth's keys and these."""

    end_reason: str  # goal, max_time, interrupted, service_failed, ...; "unknown": cut short
    failure: str  # what failed, its first line; "" otherwise
    t_end_s: float | None  # mission time at the end; null: unknown (a recording cut short)
    ticks: int | None
    runtime: str
    seed: int
    # per link: counters (int) and delays (s; null when none was measured)
    link_stats: Mapping[str, Mapping[str, int | float | None]]
    bytes_per_message: dict[str, float]  # per stream 'source/stream', bytes
    # per periodic service, mission s it was overdue (null: a run of unknown end)
    unresponsive_s: Mapping[str, float | None]
    record_rejected: dict[str, int]
    wall_s: float | msgspec.UnsetType = msgspec.UNSET  # absent: a recording's metrics


class RunMetrics(msgspec.Struct, Generic[M], kw_only=True, frozen=True):
    """A run's metrics: its mission's (M, e.g. services/mission/records.py AuvMetrics) and
    the run's facts; `to_json` is metrics.json's object, `decode` reads one back."""

    mission: M
    facts: RunFacts

    def to_json(self) -> dict[str, object]:
        """The flat object of metrics.json: schema_version, the mission's keys, the facts
        (non-finite numbers as null)."""
        flat = {
            SCHEMA_KEY: METRICS_SCHEMA,
            **msgspec.to_builtins(self.mission),
            **msgspec.to_builtins(self.facts),
        }
        out: dict[str, object] = json_safe(flat)
        return out

    def to_row(self) -> Row:
        """The run's scalar metrics by name, the columns of a sweep's results.csv (nested
        tables and nulls left out, and the schema version: it is the file's, not the run's)."""
        return {
            k: v for k, v in self.to_json().items() if isinstance(v, Scalar) and k != SCHEMA_KEY
        }

    def normalised(self) -> RunMetrics[M]:
        """This record as metrics.json gives it back (non-finite numbers as None), so the
        record a run returns equals the one read from its file."""
        return RunMetrics.decode(self.to_json(), type(self.mission))

    @staticmethod
    def decode(data: Mapping[str, object], mission: type[M], source: str = "") -> RunMetrics[M]:
        """The record of a metrics.json object; MetricsSchemaError for one of another
        schema, msgspec.ValidationError naming the key for a wrong value."""
        check_schema(data, source)
        return RunMetrics(
            mission=msgspec.convert(data, mission), facts=msgspec.convert(data, RunFacts)
        )

    @staticmethod
    def read(path: Path, mission: type[M]) -> RunMetrics[M]:
        """The record of a metrics.json file (OSError, ValueError when it cannot be read)."""
        return RunMetrics.decode(read_object(path), mission, str(path))


def read_object(path: Path) -> dict[str, object]:
    """The JSON object of a metrics file (OSError, ValueError when it holds none)."""
    data = json.loads(path.read_text())
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a metrics file holds one JSON object")
    return data


def check_schema(data: Mapping[str, object], source: str = "") -> None:
    """MetricsSchemaError unless `data` is a metrics object of METRICS_SCHEMA."""
    found = data.get(SCHEMA_KEY, 1)
    if found == METRICS_SCHEMA:
        return
    where = f"{source}: " if source else ""
    if isinstance(found, int) and found < METRICS_SCHEMA:
        raise MetricsSchemaError(
            f"{where}written by an older version of tidelink (metrics schema {found}; this "
            f"version reads schema {METRICS_SCHEMA}); re-run the run (tidelink run, launch "
            "or sweep) to write it anew"
        )
    raise MetricsSchemaError(
        f"{where}metrics schema {found!r} is not one this version of tidelink reads "
        f"(schema {METRICS_SCHEMA}): written by a newer version? Read it with that one"
    )
