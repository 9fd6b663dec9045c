"""A run's metrics as one typed record (common/runtime/metrics_record.py,
services/mission/records.py): metrics.json round-trips through it unchanged, a file of an
older schema is refused saying what to do, and a sweep's results.csv keeps its columns."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import msgspec
import pytest
from helpers.records import from_json

from common.config.scenario import load_scenario
from common.runtime.metrics_record import (
    METRICS_SCHEMA,
    SCHEMA_KEY,
    MetricsSchemaError,
    RunMetrics,
)
from common.runtime.model.inproc import run_inproc
from common.runtime.run import write_outputs
from services.experiments.sweep.grid import RunSpec
from services.experiments.sweep.worker import RunOutcome, row_of
from services.mission.records import AuvMetrics, FleetMetrics, build, read_metrics

SMALL = Path(__file__).resolve().parents[1] / "configs" / "experiments" / "scenarios" / "small.toml"


@pytest.fixture(scope="module")
def written(tmp_path_factory: pytest.TempPathFactory) -> tuple[RunMetrics[Any], Path]:
    """A short run of the AUV mission, its metrics.json written: (the record, the file)."""
    s, _ = load_scenario(SMALL, ["run.max_time_s=6.0"])
    out = tmp_path_factory.mktemp("run")
    return write_outputs(run_inproc(s), s, out, wall_s=1.25), out / "metrics.json"


def test_metrics_json_round_trips_through_the_record(
    written: tuple[RunMetrics[Any], Path],
) -> None:
    record, path = written
    text = json.loads(path.read_text())
    assert text[SCHEMA_KEY] == METRICS_SCHEMA
    assert record.to_json() == text  # the record a run returns is its file
    again = read_metrics(path)
    assert isinstance(again.mission, AuvMetrics) and again == record
    assert (
        again.facts.wall_s == 1.25 and again.mission.trajectory_sha256 == text["trajectory_sha256"]
    )
    # and once more through the JSON text (the order of keys does not matter)
    assert RunMetrics.decode(json.loads(json.dumps(text)), AuvMetrics) == record


def test_absent_and_null_metrics_stay_as_they_were() -> None:
    # an empty world measures no clearance (null); a run without a path has no xte (absent)
    m = from_json({"min_clearance_m": None, "wall_s": 2.0})
    flat = m.to_json()
    assert flat["min_clearance_m"] is None and "xte_planned_rms_m" not in flat
    assert RunMetrics.decode(flat, AuvMetrics) == m
    # a non-finite number is null in the file, as JSON has none
    inf = msgspec.structs.replace(m, mission=msgspec.structs.replace(m.mission, rho0_m=math.inf))
    assert inf.to_json()["rho0_m"] is None and inf.normalised().mission.rho0_m is None


def test_a_fleets_record_round_trips_with_its_vehicles() -> None:
    m = from_json(
        {"fleet_size": 2, "vehicles": {"auv1": {"xte_planned_rms_m": 0.1}, "auv2": {}}},
        FleetMetrics,
    )
    flat = json.loads(json.dumps(m.to_json()))
    assert flat["vehicles"]["auv1"]["xte_planned_rms_m"] == 0.1
    assert SCHEMA_KEY not in flat["vehicles"]["auv1"]  # the version is the file's
    assert RunMetrics.decode(flat, FleetMetrics) == m


def test_an_older_metrics_file_is_refused_with_its_version_and_what_to_do(
    tmp_path: Path,
) -> None:
    # metrics.json of a tidelink older than schema_version (schema 1): refused, never half
    # read (its outcome was once re-derived from `success`; such a file is re-run now)
    old = tmp_path / "metrics.json"
    old.write_text(json.dumps({"success": True, "reached_goal": True, "end_reason": "goal"}))
    with pytest.raises(MetricsSchemaError) as err:
        read_metrics(old)
    assert str(err.value) == (
        f"{old}: written by an older version of tidelink (metrics schema 1; this version reads "
        f"schema {METRICS_SCHEMA}); re-run the run (tidelink run, launch or sweep) to write it "
        "anew"
    )
    old.write_text(json.dumps({SCHEMA_KEY: METRICS_SCHEMA + 1, "success": True}))
    with pytest.raises(MetricsSchemaError, match="newer version"):
        read_metrics(old)


def test_a_wrong_value_is_named_by_its_key(tmp_path: Path) -> None:
    bad = from_json({}).to_json() | {"collisions": "none"}
    path = tmp_path / "metrics.json"
    path.write_text(json.dumps(bad))
    with pytest.raises(msgspec.ValidationError, match=r"\$\.collisions"):
        read_metrics(path)


def test_a_record_is_built_of_its_own_fields_only() -> None:
    # a misspelt key in the metrics' builder fails, rather than leave its field absent
    keys = {"trajectory_sha256": "", "controller": "nurbs", "reached_goal": False}
    fields = keys | {"outcome": "not_reached", "success": False}
    assert build(AuvMetrics, fields | {"collisions": 0}).collisions == 0
    with pytest.raises(TypeError, match="AuvMetrics has no field colisions"):
        build(AuvMetrics, fields | {"colisions": 0})
    with pytest.raises(msgspec.ValidationError, match=r"\$\.collisions"):
        build(AuvMetrics, fields | {"collisions": 0.5})


def test_to_row_is_every_scalar_of_the_file_and_results_csv_keeps_its_columns(
    written: tuple[RunMetrics[Any], Path],
) -> None:
    record, path = written
    flat = json.loads(path.read_text())
    row = record.to_row()
    # every scalar key of metrics.json but its schema version; nulls and tables left out
    scalars = {
        k: v for k, v in flat.items() if isinstance(v, bool | int | float | str) and k != SCHEMA_KEY
    }
    assert row == scalars
    assert "link_stats" not in row and "commands_rejected_by_reason" not in row
    # the results.csv row of the run: as it was built from the metrics dict before the
    # record (ids, grid labels, facts, success, on-path share, network totals, scalars)
    spec = RunSpec(run_id="r", labels={"world": "small"}, x=math.nan, seed=1, raw={})
    got = row_of(spec, RunOutcome(run_id="r", status="ok", metrics=record), "inproc", "now")
    head = ["run_id", "status", "seed", "world", "runtime", "wall_s", "finished_at", "error"]
    net = ["net_sent", "net_delivered", "net_dropped_loss", "net_dropped_outage"]
    extra = ["success", "on_path_fraction", *net, "net_dropped_queue", "net_delivery_ratio"]
    assert list(got)[: len(head) + len(extra)] == head + extra
    assert set(got) == set(head) | set(extra) | set(scalars)
    assert got["success"] is flat["success"]
    assert got["on_path_fraction"] == flat["control_actions_on_path"] / flat["control_actions"]
