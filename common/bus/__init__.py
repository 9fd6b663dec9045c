"""The typed Zenoh bus: the only module besides common.messages that imports zenoh."""

from common.bus.bus import (
    Bus,
    Event,
    Inbox,
    Liveliness,
    Publisher,
    RawFrame,
    Received,
    TypedCallback,
)
from common.bus.keys import CLOCK, Keys

__all__ = [
    "CLOCK",
    "Bus",
    "Event",
    "Inbox",
    "Keys",
    "Liveliness",
    "Publisher",
    "RawFrame",
    "Received",
    "TypedCallback",
]
