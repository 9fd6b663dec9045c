"""The graphical view of a run, as its sinks see it: the Foxglove view (services/foxglove)
turns a run's messages into ViewMessages; the live bridge serves them and the recorder writes
them to MCAP through the View protocol, without depending on the Foxglove package."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Protocol

from common.messages import Message


@dataclass(frozen=True)
class ViewMessage:
    """One message of the view: its topic, schema and encoded bytes, ready for any sink."""

    topic: str
    schema_name: str
    schema_encoding: str  # "protobuf" or "jsonschema"
    schema: bytes
    message_encoding: str  # "protobuf" or "json"
    data: bytes


class View(Protocol):
    """Turns a run's messages, in order, into view messages (FoxgloveView)."""

    def static(self) -> Sequence[ViewMessage]: ...

    def translate(self, service: str, stream: str, msg: Message) -> Sequence[ViewMessage]: ...
