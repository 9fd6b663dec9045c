"""The message base class: envelope fields shared by every wire message."""

from __future__ import annotations

import math
from dataclasses import dataclass

WIRE_VERSION = 1


class WireError(ValueError):
    """The one error `decode` raises: the bytes are not a valid tidelink message."""


def check_finite(name: str, value: float) -> None:
    """Reject NaN and infinities, which no tidelink field may carry."""
    if not math.isfinite(value):
        raise WireError(f"{name}: {value!r} is not a finite number")


def check_range(name: str, value: float, lo: float | None = None, hi: float | None = None) -> None:
    """Reject a value outside [lo, hi] with a message naming the field and the bound."""
    if lo is not None and value < lo:
        raise WireError(f"{name}: {value!r} is out of range (must be >= {lo})")
    if hi is not None and value > hi:
        raise WireError(f"{name}: {value!r} is out of range (must be <= {hi})")


@dataclass(frozen=True, kw_only=True, slots=True)
class Message:
    """Base of every wire message.

    `stamp` is the time the content refers to (sampling time of a measurement, validity time
    of an estimate or command), in seconds on the runtime clock. The envelope fields
    `source`, `seq` and `sent` are filled in by the runtime when it publishes.
    """

    stamp: float
    source: str = ""
    seq: int = 0
    sent: float = 0.0

    def __post_init__(self) -> None:
        check_finite("stamp", self.stamp)
        check_finite("sent", self.sent)
        check_range("seq", self.seq, 0, 2**63 - 1)
        self.validate()

    def validate(self) -> None:
        """Check this message's own field ranges; raise WireError. Subclasses override."""
