"""The message base classes: frozen records, the envelope every wire message carries."""

from __future__ import annotations

import math
import threading
import typing
from collections.abc import Callable
from typing import Any

import msgspec

# 5: VelocityCommand's future entries, VehicleStatus's delay figures; 6: StateEstimate's
# predicted_s (how far the estimate was carried past its newest fix); 7: LinkCounters.bytes_sent;
# 8: LinkStats.counters (what a core counted, e.g. a fleet planner's steps by intent or track);
# 9: the ocean (current, sway, Odometry, PositionFix); 10: PathMsg's reason codes; 11: PathAck;
# 12: lockstep ticks and acks carry the frames (Frame) instead of watermarks
WIRE_VERSION = 12


class WireError(ValueError):
    """The one error `decode` raises: the bytes are not a valid tidelink message."""


def check_finite(name: str, value: float) -> None:
    """Reject NaN and infinities, which no tidelink field may carry."""
    if not math.isfinite(value):
        raise WireError(f"{name}: {value!r} is not a finite number")


def check_seq(value: int) -> None:
    """Reject a seq outside the wire's [0, 2**63)."""
    if not 0 <= value < 2**63:
        raise WireError(f"seq: {value!r} is out of range (must be >= 0 and < 2**63)")


def check_range(name: str, value: float, lo: float | None = None, hi: float | None = None) -> None:
    """Reject a value outside [lo, hi] with a message naming the field and the bound."""
    if lo is not None and value < lo:
        raise WireError(f"{name}: {value!r} is out of range (must be >= {lo})")
    if hi is not None and value > hi:
        raise WireError(f"{name}: {value!r} is out of range (must be <= {hi})")


def check_non_negative(rec: Any, prefix: str, *names: str) -> None:
    """Reject any of the named fields of `rec` below 0 (named `prefix + name`)."""
    for name in names:
        value = getattr(rec, name)
        if value < 0:  # only then the name and bound are made (every record built checks)
            check_range(prefix + name, value, 0.0 if isinstance(value, float) else 0)


def _compile_common_test(cls: type) -> Callable[[Any], bool]:
    """A function telling whether a `cls` passes the checks every record shares: each float
    (and float-tuple) field finite, and a message's seq in [0, 2**63).

    Generated once per class, the way dataclasses generate __init__: one sum over the fields
    by plain attribute access is about ten times cheaper than a loop of getattr calls, and
    every message pays it when built, when stamped (codec.encode) and when decoded. x - x is
    0.0 for a finite sum and NaN otherwise. A sum can also overflow to inf with every item
    finite: the caller's field-by-field pass (_name_the_problem) then finds nothing wrong and
    lets it through.
    """
    hints = typing.get_type_hints(cls)
    names = [f.name for f in msgspec.structs.fields(cls)]
    terms = [f"r.{n}" for n in names if hints[n] is float]
    terms += [f"sum(r.{n})" for n in names if hints[n] == tuple[float, ...]]
    test = "t - t == 0.0"
    if "seq" in names:
        test += f" and 0 <= r.seq < {2**63}"
    src = f"def ok(r):\n    t = {' + '.join(terms) or '0.0'}\n    return {test}\n"
    scope: dict[str, Any] = {}
    exec(compile(src, f"<common checks of {cls.__name__}>", "exec"), scope)  # noqa: S102
    ok: Callable[[Any], bool] = scope["ok"]
    return ok


def _name_the_problem(rec: Any) -> None:
    """Raise WireError naming the first out-of-range seq, NaN or infinite float of `rec`."""
    hints = typing.get_type_hints(type(rec))
    for f in msgspec.structs.fields(type(rec)):
        v = getattr(rec, f.name)
        if f.name == "seq":
            check_seq(v)
        if hints[f.name] is float:
            check_finite(f.name, v)
        elif hints[f.name] == tuple[float, ...]:
            for i, x in enumerate(v):
                check_finite(f"{f.name}[{i}]", x)


_COMMON: dict[type, Callable[[Any], bool]] = {}


def check_common(rec: Any) -> None:
    """Raise WireError if `rec` fails the checks every record shares (finite floats, seq in
    range); the class's own `validate` is not run."""
    ok = _COMMON.get(type(rec))
    if ok is None:
        ok = _COMMON[type(rec)] = _compile_common_test(type(rec))
    if not ok(rec):
        _name_the_problem(rec)


class _Checked(threading.local):
    """Per thread: whether the records being built now passed their checks already, as
    records built from bytes this process encoded from checked records do (codec.decode_own:
    the same numbers, so the same verdict; msgspec's type checks still run, in C)."""

    on = False


# thread-local: a realtime service decodes on several threads, and only decode_own sets it
CHECKED = _Checked()


class WireRecord(msgspec.Struct, frozen=True, kw_only=True, forbid_unknown_fields=True, gc=False):
    """A frozen, keyword-only, typed record that can travel on the wire.

    msgspec's C structs rather than dataclasses: they are frozen, slotted and typed alike, but
    build, encode and decode-with-type-checks in C (a frozen dataclass's __init__ alone costs
    more than our whole encode, see scripts/bench_bus.py). Every record is checked when it is
    built *and* when it is decoded from another process's bytes: no float may be NaN or
    infinite, and `validate` enforces the class's own ranges. `gc=False`: records hold only
    numbers, strings and containers of them, never a reference cycle, so the cycle collector
    need not track them.
    """

    def __post_init__(self) -> None:
        if CHECKED.on:  # built by codec.decode_own: checked already
            return
        check_common(self)
        self.validate()

    def validate(self) -> None:
        """Check this record's own field ranges; raise WireError. Subclasses override."""


class Message(WireRecord, frozen=True, kw_only=True, tag=True):
    """Base of every wire message; its class name travels as the `type` tag.

    `stamp` is the time the content refers to (sampling time of a measurement, validity time
    of an estimate or command), in seconds on the runtime clock. The envelope fields
    `source`, `seq` and `sent` are filled in by the runtime when it publishes: a subclass's
    `validate` checks its content, never the envelope, so stamping a checked message needs
    only the shared checks again (codec.encode).
    """

    stamp: float
    source: str = ""
    seq: int = 0  # in [0, 2**63): checked with the floats (WireRecord.__post_init__)
    sent: float = 0.0
