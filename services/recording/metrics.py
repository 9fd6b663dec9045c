"""A run's metrics recomputed from its recording alone (`tidelink metrics`).

The scenario comes from the recording's metadata, the record is rebuilt from the raw frames
(a restarted service's seqs renumbered as the realtime driver does, from the recorded
liveliness), the mission computes its metrics, and the end facts come from the RunEnd. For a
recording made from the run's start (`launch --record`, or `tidelink record` started before
the mission clock), every key equals the run's own metrics.json except `wall_s`: that is
the launcher's wall-clock time, which no recording holds.
"""

from __future__ import annotations

import math
from collections.abc import Collection

import msgspec

from common.bus import CLOCK
from common.config.scenario import scenario_from_raw
from common.messages import Tick, TickAck, WireError, decode
from common.runtime.metrics_record import RunMetrics
from common.runtime.model.mission import load_mission
from common.runtime.model.record import Record, Renumbering
from common.runtime.model.result import RunResult
from common.runtime.model.seqwindow import DEFAULT_MAX_GAP, max_seq_gap
from common.runtime.run import run_metrics
from services.recording.reader import AliveEvent, Recording, RecordingError

NOT_RECOMPUTED = ("wall_s",)  # run facts a recording cannot give back


def rebuild_record(
    rec: Recording, services: Collection[str], max_seq_gap: int = DEFAULT_MAX_GAP
) -> Record:
    """The run's Record from the recorded frames (the clock's own frames left out), refusing
    what the run's own record refused (give the run's `max_seq_gap`, see mission_record)."""
    record = Record(max_seq_gap)
    renumbering = Renumbering(record)
    ever_alive: set[str] = set()
    for e in rec.events:
        if isinstance(e, AliveEvent):
            # as RealtimeDriver._liveliness: a mission service that reappears was restarted
            if e.alive and e.service in services:
                if e.service in ever_alive:
                    renumbering.rejoined(e.service)
                ever_alive.add(e.service)
            continue
        if e.service == CLOCK:
            continue
        try:
            msg = decode(e.payload)
        except WireError as exc:
            raise RecordingError(
                f"{rec.path}: a frame on {e.service}/{e.stream} at wall {e.wall:.6f} is no "
                f"tidelink message: {exc}"
            ) from None
        if not isinstance(msg, Tick | TickAck):
            renumbering.add(e.service, e.stream, msg)
    return record


def recording_metrics(rec: Recording) -> RunMetrics[msgspec.Struct]:
    """metrics.json as the run wrote it, minus NOT_RECOMPUTED; with no RunEnd in the
    recording (cut short), end_reason is "unknown" and t_end_s and ticks are None."""
    scenario = scenario_from_raw(rec.scenario_raw, f"{rec.path} (its scenario)")
    mission = load_mission(scenario)
    record = rebuild_record(
        rec, mission.dataflow.names, max_seq_gap(mission.dataflow, mission.max_time_s)
    )
    end = rec.end
    result = RunResult(
        end.reason if end is not None else "unknown",
        end.stamp if end is not None else math.nan,  # JSON null
        end.ticks if end is not None else 0,
        record,
        mission.metrics(record),
    )
    metrics = run_metrics(result, scenario, wall_s=None)
    if end is None:
        facts = msgspec.structs.replace(metrics.facts, ticks=None)
        metrics = msgspec.structs.replace(metrics, facts=facts)
    return metrics
