"""Run a scenario in the runtime it names and write its outputs (metrics.json)."""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

import msgspec

from common.config.scenario import Scenario
from common.jsonsafe import JsonObject
from common.link_table import LinkTable
from common.runtime.metrics_record import InputHealth, RunFacts, RunMetrics
from common.runtime.model.inproc import run_inproc
from common.runtime.model.mission import load_mission
from common.runtime.model.record import Record
from common.runtime.model.result import RunResult
from common.runtime.model.silence import thresholds, unresponsive_s

if TYPE_CHECKING:
    from common.messages import LinkStats


def run_scenario(scenario: Scenario, raw: JsonObject, log_dir: Path) -> RunResult:
    """Dispatch to the inproc, lockstep or realtime runtime."""
    kind = scenario.runtime.kind
    if kind == "inproc":
        return run_inproc(scenario)
    from common.runtime.processes.forkserver import warm_up

    # the fork server imports the services while this process imports them too (2 cores)
    warm_up()
    if kind == "lockstep":
        from common.runtime.distributed.lockstep import run_lockstep

        return run_lockstep(scenario, raw, log_dir)
    from common.runtime.distributed.realtime_driver import run_realtime

    return run_realtime(scenario, raw, log_dir)


def run_metrics(
    result: RunResult, scenario: Scenario, *, wall_s: float | None
) -> RunMetrics[msgspec.Struct]:
    """The mission's metrics with the run's facts added, as metrics.json gives them back;
    `wall_s` None leaves the wall-clock duration out (a recording's metrics: it is not in the
    recording)."""
    links = link_stats(result.record)
    facts = RunFacts(
        end_reason=result.reason,
        failure=result.failure.split("\n", 1)[0],  # the first line; logs have the rest
        t_end_s=result.t_end,
        ticks=result.ticks,
        runtime=scenario.runtime.kind,
        seed=scenario.run.seed,
        link_stats=links,
        # encoded size of a message per stream (what a thin link carries), in bytes
        bytes_per_message=stream_bytes(links),
        unresponsive_s=unresponsive_s(
            result.record,
            thresholds(load_mission(scenario).dataflow, scenario.runtime.stats_period_s),
            result.t_end,
        ),
        # messages the run's record refused, by reason (common/runtime/model/record.py)
        record_rejected=dict(result.record.rejected),
        **msgspec.structs.asdict(input_health(result.record)),
        wall_s=msgspec.UNSET if wall_s is None else round(wall_s, 3),
    )
    return RunMetrics(mission=result.metrics, facts=facts).normalised()


class OutputsNotWritten(OSError):
    """metrics.json could not be written (a full disk, a folder gone): the run's metrics are
    still here, in `metrics`, for the caller to report."""

    def __init__(self, path: Path, exc: OSError, metrics: RunMetrics[msgspec.Struct]) -> None:
        super().__init__(exc.errno, f"could not write {path}: {exc.strerror or exc}")
        self.metrics = metrics


def write_outputs(
    result: RunResult, scenario: Scenario, out: Path, *, wall_s: float
) -> RunMetrics[msgspec.Struct]:
    """Write out/metrics.json (atomically) and return the metrics with the run's facts added;
    OutputsNotWritten (holding the metrics) when it cannot be written, leaving no partial file."""
    metrics = run_metrics(result, scenario, wall_s=wall_s)
    tmp = out / "metrics.json.tmp"
    try:
        out.mkdir(parents=True, exist_ok=True)
        tmp.write_text(json.dumps(metrics.to_json(), indent=2, sort_keys=True))
        tmp.replace(out / "metrics.json")
    except OSError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink(missing_ok=True)
        raise OutputsNotWritten(out / "metrics.json", exc, metrics) from exc
    return metrics


def last_stats(record: Record) -> Iterator[tuple[str, LinkStats]]:
    """(service, its last LinkStats) for every service that published statistics."""
    from common.messages import LinkStats

    for service, stream in record.keys():
        last = record.last_of(service, stream, LinkStats) if stream == "stats" else None
        if last is not None:
            yield service, last


def loop_times(record: Record) -> dict[str, dict[str, int]]:
    """Each realtime service's loop phases from its last statistics, by service: the
    "loop.<phase>_<p50|p95|max>_us" counters (common/runtime/distributed/loop_times.py);
    a service that never published one is absent (inproc and lockstep runs have none)."""
    out: dict[str, dict[str, int]] = {}
    for service, stats in last_stats(record):
        if times := {k: v for k, v in stats.counters.items() if k.startswith("loop.")}:
            out[service] = times
    return out


def link_stats(record: Record) -> dict[str, dict[str, int | float]]:
    """The last LinkStats of every service, by link name: the sender's counters and modelled
    delays, and the delays the receiver measured (`measured_*`)."""
    table = LinkTable()
    for _service, last in last_stats(record):
        table.see(last)
    out: dict[str, dict[str, int | float]] = {}
    for row in table.rows():
        columns: dict[str, int | float] = {}
        out[row.link] = columns
        if (c := row.counters) is not None:
            columns.update(
                c.counts(),
                bytes_sent=c.bytes_sent,
                bytes_per_message=round(c.bytes_sent / c.sent, 1) if c.sent else 0.0,
            )
        if (d := row.measured) is not None:
            columns.update(
                measured_delay_p50_s=d.delay_p50,
                measured_delay_p95_s=d.delay_p95,
                measured_delay_max_s=d.delay_max,
            )
    return out


def stream_bytes(links: dict[str, dict[str, int | float]]) -> dict[str, float]:
    """Mean encoded bytes per message of every stream ('source/stream'), from its links
    (each receiver's link sees the same messages: the busiest one counts)."""
    out: dict[str, tuple[int | float, int | float]] = {}  # stream -> (sent, bytes_sent)
    for name, c in links.items():
        stream = name.split("->", 1)[0]
        if "sent" in c and c["sent"] > out.get(stream, (0, 0))[0]:
            out[stream] = (c["sent"], c["bytes_sent"])
    return {k: round(b / n, 1) for k, (n, b) in sorted(out.items())}


def input_health(record: Record) -> InputHealth:
    """How the services' inputs fared, from each service's last LinkStats: inputs its core
    rejected as implausible (by service, then '<stream>.<reason>'), deliveries dropped because
    an input's queue was full (by link), filters restarted (by service, then filter); with
    the totals as scalars (a sweep's results.csv keeps those)."""
    from common.messages import LinkStats

    rejected: dict[str, dict[str, int]] = {}
    dropped: dict[str, int] = {}
    resets: dict[str, dict[str, int]] = {}
    for service, stream in record.keys():
        if stream != "stats":
            continue
        msgs = [m for m in record.stream(service, stream) if isinstance(m, LinkStats)]
        if not msgs:
            continue
        last = msgs[-1]
        if last.inputs_rejected:
            rejected[service] = dict(sorted(last.inputs_rejected.items()))
        dropped.update(last.inputs_dropped)
        if last.resets:
            resets[service] = dict(sorted(last.resets.items()))
    return InputHealth(
        inputs_rejected=sum(n for by in rejected.values() for n in by.values()),
        inputs_rejected_by_reason=rejected,
        inputs_dropped=sum(dropped.values()),
        inputs_dropped_by_link=dict(sorted(dropped.items())),
        filter_resets=sum(n for by in resets.values() for n in by.values()),
        filter_resets_by_service=resets,
    )
