"""The message base classes: frozen records, the envelope every wire message carries."""

from __future__ import annotations

import math
import typing
from operator import attrgetter
from typing import Any

import msgspec

WIRE_VERSION = 2


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


class _FloatFields:
    """The float and float-tuple fields of one record class, read in one C call each."""

    def __init__(self, cls: type) -> None:
        hints = typing.get_type_hints(cls)
        names = [f.name for f in msgspec.structs.fields(cls)]
        self.scalars = tuple(n for n in names if hints[n] is float)
        self.tuples = tuple(n for n in names if hints[n] == tuple[float, ...])
        self.get_scalars = attrgetter(*self.scalars) if len(self.scalars) > 1 else None
        self.get_tuples = attrgetter(*self.tuples) if len(self.tuples) > 1 else None

    def check(self, rec: Any) -> None:
        """Raise WireError naming the first NaN or infinite float of `rec`."""
        # x - x is 0.0 for every finite sum and NaN otherwise: one test for all the fields.
        # A sum can overflow to inf with every item finite; the field-by-field pass then
        # finds nothing and lets the record through.
        if self.get_scalars is not None:
            total = sum(self.get_scalars(rec))
        else:
            total = sum(getattr(rec, n) for n in self.scalars)
        if self.get_tuples is not None:
            total += sum(map(sum, self.get_tuples(rec)))
        else:
            total += sum(sum(getattr(rec, n)) for n in self.tuples)
        if total - total == 0.0:
            return
        for n in self.scalars:
            check_finite(n, getattr(rec, n))
        for n in self.tuples:
            for i, v in enumerate(getattr(rec, n)):
                check_finite(f"{n}[{i}]", v)


_FLOATS: dict[type, _FloatFields] = {}


class WireRecord(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True, gc=False):
    """A frozen, keyword-only, typed record that can travel on the wire.

    msgspec's C structs rather than dataclasses: they are frozen, slotted and typed alike, but
    build, encode and decode-with-type-checks in C (a frozen dataclass's __init__ alone costs
    more than our whole encode, see scripts/bench_bus.py). Every record is checked when it is
    built *and* when it is decoded: no float may be NaN or infinite, and `validate` enforces
    the class's own ranges. `gc=False`: records hold only numbers, strings and containers of
    them, never a reference cycle, so the cycle collector need not track them.
    """

    def __post_init__(self) -> None:
        cls = type(self)
        floats = _FLOATS.get(cls)
        if floats is None:
            floats = _FLOATS[cls] = _FloatFields(cls)
        floats.check(self)
        self.validate()

    def validate(self) -> None:
        """Check this record's own field ranges; raise WireError. Subclasses override."""


class Message(WireRecord, frozen=True, kw_only=True, tag=True):
    """Base of every wire message; its class name travels as the `type` tag.

    `stamp` is the time the content refers to (sampling time of a measurement, validity time
    of an estimate or command), in seconds on the runtime clock. The envelope fields
    `source`, `seq` and `sent` are filled in by the runtime when it publishes.
    """

    stamp: float
    source: str = ""
    seq: int = 0
    sent: float = 0.0

    def __post_init__(self) -> None:
        if not 0 <= self.seq < 2**63:
            raise WireError(f"seq: {self.seq!r} is out of range (must be >= 0 and < 2**63)")
        WireRecord.__post_init__(self)
