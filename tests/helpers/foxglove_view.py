"""Shared by the Foxglove tests: a short in-process run of the default scenario fed through
the view, and checks that a view message is what its schema says."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from common.config.scenario import Scenario, load_scenario
from common.messages import Message
from common.runtime.model.inproc import run_inproc
from helpers.protobuf_wire import Schemas
from services.foxglove.view import FoxgloveView, ViewMessage

REPO = Path(__file__).resolve().parents[2]
JSON_TYPES: dict[str, tuple[type, ...]] = {
    "number": (int, float),
    "integer": (int,),
    "string": (str,),
    "boolean": (bool,),
    "array": (list,),
    "object": (dict,),
}


def short_run(
    max_time_s: float = 8.0, scenario: Path = REPO / "configs" / "default.toml"
) -> tuple[Scenario, list[tuple[str, str, Message]]]:
    """A scenario (the default one) run in-process for max_time_s: every message as
    (service, stream, msg), in stamp order (publication order within a stream)."""
    s, _ = load_scenario(scenario, [f"run.max_time_s={max_time_s}"])
    record = run_inproc(s).record
    frames = [(svc, st, m) for svc, st in record.keys() for m in record.stream(svc, st)]
    frames.sort(key=lambda f: f[2].stamp)  # stable: keeps each stream's own order
    return s, frames


def view_all(s: Scenario, frames: list[tuple[str, str, Message]]) -> list[ViewMessage]:
    view = FoxgloveView(s)
    out = view.static()
    for svc, st, m in frames:
        out += view.translate(svc, st, m)
    return out


def _check_json(value: Any, schema: dict[str, Any], where: str) -> None:
    kind = schema.get("type")
    if kind is not None:
        ok = isinstance(value, JSON_TYPES[kind]) and not (
            kind in ("number", "integer") and isinstance(value, bool)
        )
        assert ok, f"{where}: {value!r} is not a JSON {kind}"
    if kind == "object":
        props = schema.get("properties", {})
        for name in schema.get("required", []):
            assert name in value, f"{where}: required field {name!r} is missing"
        for name, v in value.items():
            assert name in props, f"{where}: field {name!r} is not in the schema"
            _check_json(v, props[name], f"{where}.{name}")
    if kind == "array":
        for i, v in enumerate(value):
            _check_json(v, schema.get("items", {}), f"{where}[{i}]")


def decode(vm: ViewMessage) -> dict[str, Any]:
    """A view message's content, decoded with nothing but its own schema (and checked
    against it for JSON)."""
    if vm.message_encoding == "protobuf":
        assert vm.schema_encoding == "protobuf"
        return Schemas(vm.schema).decode(f".{vm.schema_name}", vm.data)
    assert (vm.message_encoding, vm.schema_encoding) == ("json", "jsonschema")
    schema = json.loads(vm.schema)
    assert schema["title"] == vm.schema_name
    value = json.loads(vm.data)
    _check_json(value, schema, vm.topic)
    assert isinstance(value, dict)
    return value
