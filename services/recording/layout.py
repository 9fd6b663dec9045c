"""The layout of a tidelink MCAP recording: its metadata, channels and schemas, in one place.

A recording holds what crossed the wire, byte for byte, so a run can be replayed and its
metrics recomputed from the file alone:

- metadata `tidelink`: format, wire_version, run, vehicle, recorder and the scenario (JSON);
- channel `/wire/<service>/<stream>` per stream (message encoding `msgpack`): each MCAP
  message is a frame as published, `[wire_version, message]`; schema `tidelink.<Type>` (JSON
  Schema of that array); log_time = when the run's watch tap got it (Unix ns); sequence =
  the message's seq (mod 2**32, MCAP's field is 32-bit); `/wire/runtime/end` is the RunEnd;
- channel `/wire/<service>/<stream>/routing`: a frame's attachment (the runtime's routing:
  `[tick, {receiver: [delivery us, ...]}]`), written right after its frame with the same
  log_time and sequence; frames without an attachment have none;
- channel `/alive` (JSON `{"service": name, "alive": bool}`): liveliness tokens appearing
  and vanishing, as the recorder saw them;
- any other channel: the Foxglove view (scene, series: services/foxglove/view.py) made of
  the frames as they were written, so the file opens in Foxglove as it is (Foxglove does
  not decode msgpack: the /wire channels are for tidelink's tools). Readers of the raw run
  skip them.

Each channel's metadata says which kind it is (key `tidelink`).
"""

from __future__ import annotations

import json
import logging
from collections.abc import Mapping

import msgspec

from common.bus import CLOCK
from common.bus.keys import END
from common.config.scenario import Scenario
from common.messages import WIRE_VERSION, LinkStats, Message, RunEnd
from common.runtime.model.host import STATS_STREAM
from common.runtime.model.mission import load_mission

log = logging.getLogger("tidelink.recording")

FORMAT_VERSION = 1
PROFILE = "tidelink"
METADATA = "tidelink"  # the name of the recording's metadata record
KIND = "tidelink"  # channel metadata key naming the channel's kind:
FRAME, ROUTING, ALIVE, VIEW = "frame", "routing", "alive", "view"
RAW_ENCODING = "msgpack"
ALIVE_TOPIC = "/alive"
ALIVE_SCHEMA_NAME = "tidelink.Liveliness"
ROUTING_SCHEMA_NAME = "tidelink.Routing"

StreamTypes = Mapping[tuple[str, str], type[Message]]


def stream_name(service: str, stream: str) -> str:
    """How reports name a stream: 'sensor/nav'."""
    return f"{service}/{stream}"


def frame_topic(service: str, stream: str) -> str:
    return f"/wire/{service}/{stream}"


def routing_topic(service: str, stream: str) -> str:
    return f"/wire/{service}/{stream}/routing"


def stream_types(scenario: Scenario) -> dict[tuple[str, str], type[Message]]:
    """The message type of every stream a run of `scenario` publishes: its mission's declared
    outputs, each service's link statistics, and the clock's RunEnd. If the mission cannot be
    loaded here (a recorder without the mission's code), none: the writer then takes each
    stream's type from its first message."""
    try:
        flow = load_mission(scenario).dataflow
    except ValueError as exc:
        log.warning("schemas from the first message of each stream: %s", exc)
        return {}
    out: dict[tuple[str, str], type[Message]] = {
        (s.name, o.stream): o.msg_type for s in flow.services.values() for o in s.outputs
    }
    out.update({(name, STATS_STREAM): LinkStats for name in flow.names})
    out[(CLOCK, END)] = RunEnd
    return out


def _json(schema: dict[str, object]) -> bytes:
    return json.dumps(schema, sort_keys=True).encode()


def frame_schema(cls: type[Message]) -> tuple[str, bytes]:
    """Name and JSON Schema of a frame carrying `cls`: the array [wire_version, message]."""
    inner = msgspec.json.schema(cls)
    return f"tidelink.{cls.__name__}", _json(
        {
            "title": f"tidelink.{cls.__name__} frame",
            "description": "A tidelink wire frame (MessagePack): [wire_version, message].",
            "type": "array",
            "prefixItems": [{"const": WIRE_VERSION}, {"$ref": inner["$ref"]}],
            "items": False,
            "minItems": 2,
            "$defs": inner["$defs"],
        }
    )


ROUTING_SCHEMA = _json(
    {
        "title": ROUTING_SCHEMA_NAME,
        "description": "A frame's routing attachment: [tick, {receiver: [delivery_us, ...]}].",
        **msgspec.json.schema(tuple[int, dict[str, tuple[int, ...]]]),
    }
)
ALIVE_SCHEMA = _json(
    {
        "title": ALIVE_SCHEMA_NAME,
        "description": "A service's liveliness token appeared (alive) or vanished.",
        "type": "object",
        "properties": {"service": {"type": "string"}, "alive": {"type": "boolean"}},
        "required": ["service", "alive"],
    }
)
