"""The wire codec: msgpack bodies in a versioned envelope; strict decoding to one error type."""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable
from typing import Any

import msgpack

from common.messages.base import WIRE_VERSION, Message, WireError
from common.messages.types import MESSAGE_TYPES

# A converter turns one decoded msgpack value into the field's Python value, or raises WireError.
Converter = Callable[[str, Any], Any]
Encoder = Callable[[Any], Any]

_ENVELOPE = ("stamp", "source", "seq", "sent")
_MAX_BYTES = 16 * 1024 * 1024


def _float(name: str, v: Any) -> float:
    t = type(v)
    if t is float:
        if not math.isfinite(v):
            raise WireError(f"{name}: {v!r} is not a finite number")
        return v  # type: ignore[no-any-return]
    if t is int:
        return float(v)
    raise WireError(f"{name}: expected a number, got {t.__name__}")


def _int(name: str, v: Any) -> int:
    if type(v) is not int:
        raise WireError(f"{name}: expected an integer, got {type(v).__name__}")
    return v  # type: ignore[no-any-return]


def _str(name: str, v: Any) -> str:
    if type(v) is not str:
        raise WireError(f"{name}: expected a string, got {type(v).__name__}")
    return v  # type: ignore[no-any-return]


def _bool(name: str, v: Any) -> bool:
    if type(v) is not bool:
        raise WireError(f"{name}: expected true/false, got {type(v).__name__}")
    return v  # type: ignore[no-any-return]


def _literal(allowed: tuple[str, ...]) -> Converter:
    def conv(name: str, v: Any) -> str:
        if v not in allowed or type(v) is not str:
            raise WireError(f"{name}: {v!r} is not one of {', '.join(allowed)}")
        return v  # type: ignore[no-any-return]

    return conv


def _tuple_of(item: Converter) -> Converter:
    def conv(name: str, v: Any) -> tuple[Any, ...]:
        if type(v) is not list:
            raise WireError(f"{name}: expected a list, got {type(v).__name__}")
        return tuple(item(f"{name}[{i}]", x) for i, x in enumerate(v))

    return conv


def _dict_str_int(name: str, v: Any) -> dict[str, int]:
    if type(v) is not dict:
        raise WireError(f"{name}: expected a map, got {type(v).__name__}")
    return {_str(f"{name} key", k): _int(f"{name}[{k!r}]", x) for k, x in v.items()}


_SCALARS: dict[Any, Converter] = {float: _float, int: _int, str: _str, bool: _bool}


class _Schema:
    """Field converters and encoders of one dataclass, derived once from its type hints."""

    def __init__(self, cls: type) -> None:
        self.cls = cls
        hints = typing.get_type_hints(cls)
        # envelope fields travel in the envelope, but only a Message has them
        skip = _ENVELOPE if issubclass(cls, Message) else ()
        names = [f.name for f in dataclasses.fields(cls) if f.name not in skip]
        self.fields: dict[str, Converter] = {}
        self.encoders: dict[str, Encoder] = {}
        self.required = frozenset(
            f.name
            for f in dataclasses.fields(cls)
            if f.name not in skip
            and f.default is dataclasses.MISSING
            and f.default_factory is dataclasses.MISSING
        )
        for name in names:
            self.fields[name], self.encoders[name] = self._compile(hints[name])

    def _compile(self, hint: Any) -> tuple[Converter, Encoder]:
        if hint in _SCALARS:
            return _SCALARS[hint], (float if hint is float else _identity)
        origin = typing.get_origin(hint)
        args = typing.get_args(hint)
        if origin is typing.Literal:
            return _literal(tuple(args)), _identity
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            item_conv, item_enc = self._compile(args[0])
            if item_enc is _identity:
                return _tuple_of(item_conv), list
            return _tuple_of(item_conv), lambda v: [item_enc(x) for x in v]
        if origin is dict and args == (str, int):
            return _dict_str_int, _identity
        if dataclasses.is_dataclass(hint) and isinstance(hint, type):
            nested = _Schema(hint)
            return nested.convert, nested.encode
        if origin is types.UnionType or origin is typing.Union:
            raise TypeError(f"{self.cls.__name__}: optional fields are not on the wire ({hint})")
        raise TypeError(f"{self.cls.__name__}: unsupported field type {hint!r}")

    def encode(self, obj: Any) -> dict[str, Any]:
        return {name: enc(getattr(obj, name)) for name, enc in self.encoders.items()}

    def convert(self, where: str, body: Any, envelope: dict[str, Any] | None = None) -> Any:
        if type(body) is not dict:
            raise WireError(f"{where}: expected a map of fields, got {type(body).__name__}")
        extra = body.keys() - self.fields.keys()
        if extra:
            raise WireError(f"{where}: unexpected field(s) {', '.join(sorted(map(str, extra)))}")
        missing = self.required - body.keys()
        if missing:
            raise WireError(f"{where}: missing field(s) {', '.join(sorted(missing))}")
        kwargs = {name: self.fields[name](f"{where}.{name}", v) for name, v in body.items()}
        if envelope:
            kwargs.update(envelope)
        return self.cls(**kwargs)


def _identity(v: Any) -> Any:
    return v


_BY_NAME: dict[str, _Schema] = {cls.__name__: _Schema(cls) for cls in MESSAGE_TYPES}
_BY_CLASS: dict[type, tuple[str, _Schema]] = {s.cls: (n, s) for n, s in _BY_NAME.items()}


def encode(msg: Message) -> bytes:
    """Serialise a message: [version, type, source, seq, stamp, sent, {field: value}]."""
    try:
        name, schema = _BY_CLASS[type(msg)]
    except KeyError:
        raise WireError(f"cannot encode {type(msg).__name__}: not a tidelink message type") from None
    return msgpack.packb(  # type: ignore[no-any-return]
        [WIRE_VERSION, name, msg.source, msg.seq, float(msg.stamp), float(msg.sent),
         schema.encode(msg)],
        use_bin_type=True,
    )


def decode(data: bytes) -> Message:
    """Parse and validate bytes into a message; any problem raises WireError, nothing else."""
    try:
        return _decode(data)
    except WireError:
        raise
    except Exception as exc:  # noqa: BLE001 - the contract: no other exception type escapes
        raise WireError(f"malformed message: {type(exc).__name__}: {exc}") from None


def _decode(data: bytes) -> Message:
    if not isinstance(data, bytes | bytearray | memoryview):
        raise WireError(f"expected bytes, got {type(data).__name__}")
    if len(data) == 0:
        raise WireError("empty payload")
    if len(data) > _MAX_BYTES:
        raise WireError(f"payload of {len(data)} bytes exceeds the {_MAX_BYTES}-byte limit")
    try:
        frame = msgpack.unpackb(data, raw=False, strict_map_key=True)
    except msgpack.ExtraData:
        raise WireError("trailing bytes after the message") from None
    except (ValueError, msgpack.UnpackException) as exc:
        raise WireError(f"truncated or invalid msgpack: {exc}") from None
    if type(frame) is not list or len(frame) != 7:
        raise WireError("not a tidelink envelope (expected a 7-element array)")
    version, name, source, seq, stamp, sent, body = frame
    if version != WIRE_VERSION or type(version) is not int:
        raise WireError(f"wrong wire version {version!r} (this build speaks {WIRE_VERSION})")
    if type(name) is not str:
        raise WireError("type name: expected a string")
    schema = _BY_NAME.get(name)
    if schema is None:
        raise WireError(f"unknown message type {name!r}")
    envelope = {
        "source": _str("source", source),
        "seq": _int("seq", seq),
        "stamp": _float("stamp", stamp),
        "sent": _float("sent", sent),
    }
    msg: Message = schema.convert(name, body, envelope)
    return msg


def encode_routing(tick: int, deliveries: dict[str, tuple[int, ...]]) -> bytes:
    """The attachment a runtime sends with a message: its tick and modelled delivery times (us)
    per receiving service (an empty tuple: the model dropped it for that receiver)."""
    return msgpack.packb([tick, {k: list(v) for k, v in deliveries.items()}])  # type: ignore[no-any-return]


def decode_routing(data: bytes) -> tuple[int, dict[str, tuple[int, ...]]]:
    """Parse a routing attachment; WireError on anything malformed."""
    try:
        tick, deliveries = msgpack.unpackb(data, raw=False, strict_map_key=True)
        if type(tick) is not int or type(deliveries) is not dict:
            raise WireError("routing attachment: expected [tick, {service: [us, ...]}]")
        out = {}
        for k, v in deliveries.items():
            if type(k) is not str or type(v) is not list or any(type(x) is not int for x in v):
                raise WireError("routing attachment: delivery times must be integer microseconds")
            out[k] = tuple(v)
        return tick, out
    except WireError:
        raise
    except Exception as exc:  # noqa: BLE001 - same contract as decode
        raise WireError(f"malformed routing attachment: {type(exc).__name__}: {exc}") from None
