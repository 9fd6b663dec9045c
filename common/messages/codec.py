"""The wire codec: MessagePack frames [version, {type, envelope, fields}], strictly decoded.

The codec is msgspec's MessagePack encoder and typed decoder (C): one call checks every field's
type, the exact field set, literals, nesting, and runs each record's own checks. Only when that
fails do we take the slow road, to turn msgspec's report into an error that names the message
type and field in our words. This module is the only place that names the codec.
"""

from __future__ import annotations

import copy
import re
import threading
from collections.abc import Mapping
from typing import Any, Literal, Union

import msgspec

from common.messages.base import (
    CHECKED,
    WIRE_VERSION,
    Message,
    WireError,
    check_finite,
    check_seq,
)
from common.messages.types import MESSAGE_TYPES

_MAX_BYTES = 16 * 1024 * 1024
_TYPE_NAMES = {cls.__name__ for cls in MESSAGE_TYPES}

# One frame type for all: msgspec picks the class from the `type` tag in a single C call.
_AnyMessage = Union[tuple(MESSAGE_TYPES)]  # type: ignore[valid-type]  # noqa: UP007
_Frame = tuple[Literal[12], _AnyMessage]  # type: ignore[valid-type]
assert WIRE_VERSION == 12, "update _Frame with the wire version"


class _Codec(threading.local):
    """msgspec's encoder and decoder for this thread (they keep internal buffers)."""

    def __init__(self) -> None:
        self.encode = msgspec.msgpack.Encoder().encode
        self.decode = msgspec.msgpack.Decoder(_Frame).decode
        self.decode_routing = msgspec.msgpack.Decoder(tuple[int, dict[str, tuple[int, ...]]]).decode
        self.decode_watch = msgspec.msgpack.Decoder(tuple[float, int, bytes | None]).decode


_CODEC = _Codec()


def encode(
    msg: Message, *, source: str | None = None, seq: int | None = None, sent: float | None = None
) -> bytes:
    """Serialise a message as [version, {"type": name, stamp, source, seq, sent, fields...}].

    `source`, `seq` and `sent` override the envelope fields, so a runtime can stamp a message
    it did not build (a C-level copy, checked again as far as the envelope can fail: _stamped).
    """
    if type(msg) not in _CLASSES:
        raise WireError(f"cannot encode {type(msg).__name__}: not a tidelink message type")
    if source is not None or seq is not None or sent is not None:
        msg = _stamped(msg, source, seq, sent)
    try:
        data: bytes = _CODEC.encode((WIRE_VERSION, msg))
    except (msgspec.EncodeError, TypeError, ValueError, OverflowError) as exc:
        # a field built with a value msgspec cannot write (e.g. a numpy array for a tuple)
        raise WireError(f"cannot encode {type(msg).__name__}: {exc}") from None
    return data


_CLASSES = frozenset(MESSAGE_TYPES)


def fields_of(msg: Message) -> dict[str, object]:
    """A message's fields by name, envelope included (what forge_frame takes back)."""
    return {f: getattr(msg, f) for f in msg.__struct_fields__}


def forge_frame(type_name: str, fields: Mapping[str, object]) -> bytes:
    """A frame as a buggy or hostile peer could send it: the wire layout with no checks at
    all (NaN, a stamp in Unix time, a seq of 2**62...). For fault injection only
    (services/chaos); every receiver must survive what this makes."""
    frame = (WIRE_VERSION, {"type": type_name, **fields})
    data: bytes = _CODEC.encode(frame)
    return data


def _stamped(msg: Message, source: str | None, seq: int | None, sent: float | None) -> Message:
    """A copy of `msg` with these envelope fields (None: unchanged), refused as `replace`
    would refuse it: only the shared checks of the new envelope fields (seq in range, sent
    finite, in that order, as check_common names them) can fail, as a message type's
    `validate` never reads the envelope (Message) and `msg`'s other fields passed every check
    when it was built; running them again cost more than the rest of a publish."""
    out = copy.copy(msg)  # msgspec's C-level copy: no __post_init__
    if source is not None:
        msgspec.structs.force_setattr(out, "source", source)
    if seq is not None:
        check_seq(seq)
        msgspec.structs.force_setattr(out, "seq", seq)
    if sent is not None:
        check_finite("sent", sent)
        msgspec.structs.force_setattr(out, "sent", sent)
    return out


def replace(msg: Message, **changes: Any) -> Message:
    """A copy of `msg` with some fields changed (checked like a newly built message)."""
    try:
        out: Message = msgspec.structs.replace(msg, **changes)
    except TypeError as exc:
        raise WireError(f"{type(msg).__name__}: {exc}") from None
    return out


def decode(data: bytes) -> Message:
    """Parse and validate bytes into a message; any problem raises WireError, nothing else."""
    if type(data) is not bytes and not isinstance(data, (bytearray, memoryview)):
        raise WireError(f"expected bytes, got {type(data).__name__}")
    n = len(data)
    if n == 0 or n > _MAX_BYTES:
        raise WireError(
            "empty payload"
            if n == 0
            else f"payload of {n} bytes exceeds the {_MAX_BYTES}-byte limit"
        )
    try:
        frame = _CODEC.decode(data)
    except msgspec.ValidationError as exc:  # a subclass of DecodeError: test it first
        try:
            why = _explain_invalid(data, str(exc))
        except Exception:  # noqa: BLE001 - explaining must never hide the error itself
            why = f"invalid message: {exc}"
        raise WireError(why) from None
    except msgspec.DecodeError as exc:
        raise WireError(_explain_decode_error(str(exc))) from None
    except Exception as exc:  # noqa: BLE001 - the contract: no other exception type escapes
        raise WireError(f"malformed message: {type(exc).__name__}: {exc}") from None
    msg: Message = frame[1]
    return msg


def decode_own(data: bytes) -> Message:
    """`decode` for bytes this process's `encode` made from checked messages (the inproc
    runtime's wire): the same parse and type checks, without running each record's own checks
    a second time: its numbers are the ones that passed them when it was built."""
    CHECKED.on = True
    try:
        return decode(data)
    finally:
        CHECKED.on = False


def _explain_decode_error(text: str) -> str:
    """msgspec's report on bytes that are not MessagePack at all, in our words."""
    if "trailing" in text:
        return "trailing bytes after the message"
    return f"truncated or invalid msgpack: {text}"


# msgspec ends a validation report with the place: "... - at `$[1].tracks[0].covariance`"
_AT = re.compile(r"^(?P<what>.*?)(?: - at `\$(?P<path>[^`]*)`)?$", re.DOTALL)


def _explain_invalid(data: bytes, text: str) -> str:
    """msgspec's report on a well-formed MessagePack value that is no valid frame, our words.

    Only reached on an error, so it may decode the bytes again untyped to see what they hold.
    """
    m = _AT.match(text)
    what, path = (m["what"], m["path"] or "") if m else (text, "")
    try:
        raw = msgspec.msgpack.decode(data)
    except Exception:  # noqa: BLE001 - typed decoding already parsed it; be safe anyway
        raw = None
    # the version comes first in every version's frame, whatever the rest looks like
    if type(raw) is list and raw and type(raw[0]) is int and raw[0] != WIRE_VERSION:
        return f"wrong wire version {raw[0]!r} (this build speaks {WIRE_VERSION})"
    if type(raw) is not list or len(raw) != 2:
        return f"not a tidelink envelope (expected a 2-element array [version, message]): {what}"
    version, body = raw
    if type(version) is not int or version != WIRE_VERSION:
        return f"wrong wire version {version!r} (this build speaks {WIRE_VERSION})"
    if type(body) is not dict:
        return f"expected a map of fields for the message, got {_kind(body)}"
    name = body.get("type")
    if type(name) is not str or name not in _TYPE_NAMES:
        return f"unknown message type {name!r}" if "type" in body else "no message type given"
    # "$[1].x" -> "NavFix.x"; "$[1]" -> "NavFix"
    where = str(name) + path.removeprefix("[1]")
    return f"{where}: {_lower_first(what)}"


def _kind(v: Any) -> str:
    kinds: dict[type, str] = {list: "an array", dict: "a map"}
    return kinds.get(type(v), type(v).__name__)


def _lower_first(s: str) -> str:
    return s[:1].lower() + s[1:] if s[:1].isupper() and s[1:2].islower() else s


def encode_routing(tick: int, deliveries: dict[str, tuple[int, ...]]) -> bytes:
    """The attachment a runtime sends with a message: its tick and modelled delivery times (us)
    per receiving service (an empty tuple: the model dropped it for that receiver)."""
    data: bytes = _CODEC.encode((tick, deliveries))
    return data


def decode_routing(data: bytes) -> tuple[int, dict[str, tuple[int, ...]]]:
    """Parse a routing attachment; WireError on anything malformed."""
    try:
        tick, deliveries = _CODEC.decode_routing(data)
    except Exception as exc:  # noqa: BLE001 - same contract as decode
        raise WireError(
            f"malformed routing attachment (expected [tick, {{service: [us, ...]}}]): {exc}"
        ) from None
    return tick, deliveries


def encode_watch(wall: float, n: int, attachment: bytes | None) -> bytes:
    """The attachment of a monitoring copy (Keys.watch, Keys.latest): when the run's tap got
    the frame (Unix seconds), the tap's running count, and the frame's own attachment."""
    data: bytes = _CODEC.encode((wall, n, attachment))
    return data


def decode_watch(data: bytes) -> tuple[float, int, bytes | None]:
    """Parse a monitoring copy's attachment; WireError on anything malformed."""
    try:
        wall, n, att = _CODEC.decode_watch(data)
    except Exception as exc:  # noqa: BLE001 - same contract as decode
        raise WireError(
            f"malformed watch attachment (expected [wall_s, count, attachment]): {exc}"
        ) from None
    return wall, n, att
