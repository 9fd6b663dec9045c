"""The wire codec: msgpack bodies in a versioned envelope; strict decoding to one error type."""

from __future__ import annotations

import dataclasses
import math
import threading
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
# A fast converter does the same for the common, valid case without building field names; it
# returns _SLOW for anything unusual, and the checked converters then decide and name the error.
# So the fast path only ever returns what the checked path would have returned.
FastConverter = Callable[[Any], Any]
_SLOW: Any = object()

_ENVELOPE = ("stamp", "source", "seq", "sent")
_MAX_BYTES = 16 * 1024 * 1024


def _float(name: str, v: Any) -> float:
    t = type(v)
    if t is float:
        if not math.isfinite(v):
            raise WireError(f"{name}: {v!r} is not a finite number")
        return v
    if t is int:
        return float(v)
    raise WireError(f"{name}: expected a number, got {t.__name__}")


def _int(name: str, v: Any) -> int:
    if type(v) is not int:
        raise WireError(f"{name}: expected an integer, got {type(v).__name__}")
    return v


def _str(name: str, v: Any) -> str:
    if type(v) is not str:
        raise WireError(f"{name}: expected a string, got {type(v).__name__}")
    return v


def _bool(name: str, v: Any) -> bool:
    if type(v) is not bool:
        raise WireError(f"{name}: expected true/false, got {type(v).__name__}")
    return v


def _literal(allowed: tuple[str, ...]) -> Converter:
    def conv(name: str, v: Any) -> str:
        if v not in allowed or type(v) is not str:
            raise WireError(f"{name}: {v!r} is not one of {', '.join(allowed)}")
        return v

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


def _fast_float(v: Any) -> Any:
    # x - x is 0.0 exactly for every finite float, NaN for NaN and the infinities
    return v if type(v) is float and v - v == 0.0 else _SLOW


def _fast_exact(t: type) -> FastConverter:
    def conv(v: Any) -> Any:
        return v if type(v) is t else _SLOW

    return conv


def _fast_literal(allowed: tuple[str, ...]) -> FastConverter:
    names = frozenset(allowed)

    def conv(v: Any) -> Any:
        return v if type(v) is str and v in names else _SLOW

    return conv


_FLOAT_ONLY = {float}


def _fast_floats(v: Any) -> Any:
    """A list of finite floats as a tuple (covariances, knots: the long lists on the wire)."""
    if type(v) is not list:
        return _SLOW
    if not v:
        return ()
    if set(map(type, v)) != _FLOAT_ONLY:
        return _SLOW
    total = sum(v)  # finite if every item is (an overflow only sends us to the checked path)
    return tuple(v) if total - total == 0.0 else _SLOW


def _fast_tuple_of(item: FastConverter) -> FastConverter:
    def conv(v: Any) -> Any:
        if type(v) is not list:
            return _SLOW
        out = []
        for x in v:
            y = item(x)
            if y is _SLOW:
                return _SLOW
            out.append(y)
        return tuple(out)

    return conv


def _fast_dict_str_int(v: Any) -> Any:
    if type(v) is not dict:
        return _SLOW
    for k, x in v.items():
        if type(k) is not str or type(x) is not int:
            return _SLOW
    return v


_FAST_SCALARS: dict[Any, FastConverter] = {
    float: _fast_float,
    int: _fast_exact(int),
    str: _fast_exact(str),
    bool: _fast_exact(bool),
}


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
        fast: dict[str, FastConverter] = {}
        self.required = frozenset(
            f.name
            for f in dataclasses.fields(cls)
            if f.name not in skip
            and f.default is dataclasses.MISSING
            and f.default_factory is dataclasses.MISSING
        )
        for name in names:
            self.fields[name], self.encoders[name], fast[name] = self._compile(hints[name])
        # Fast path plan: the exact key set of an encoded body (encode writes every field),
        # finite-float fields checked inline, the others through their fast converters.
        self.keyset = frozenset(names)
        self.float_names = tuple(n for n in names if fast[n] is _fast_float)
        self.fast_others = tuple((n, f) for n, f in fast.items() if f is not _fast_float)

    def _compile(self, hint: Any) -> tuple[Converter, Encoder, FastConverter]:
        if hint in _SCALARS:
            return _SCALARS[hint], (float if hint is float else _identity), _FAST_SCALARS[hint]
        origin = typing.get_origin(hint)
        args = typing.get_args(hint)
        if origin is typing.Literal:
            return _literal(tuple(args)), _identity, _fast_literal(tuple(args))
        if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
            item_conv, item_enc, item_fast = self._compile(args[0])
            fast = _fast_floats if item_fast is _fast_float else _fast_tuple_of(item_fast)
            if item_enc is _identity:
                return _tuple_of(item_conv), list, fast
            return _tuple_of(item_conv), lambda v: [item_enc(x) for x in v], fast
        if origin is dict and args == (str, int):
            return _dict_str_int, _identity, _fast_dict_str_int
        if dataclasses.is_dataclass(hint) and isinstance(hint, type):
            nested = _Schema(hint)
            return nested.convert, nested.encode, nested.fast_convert
        if origin is types.UnionType or origin is typing.Union:
            raise TypeError(f"{self.cls.__name__}: optional fields are not on the wire ({hint})")
        raise TypeError(f"{self.cls.__name__}: unsupported field type {hint!r}")

    def encode(self, obj: Any) -> dict[str, Any]:
        return {name: enc(getattr(obj, name)) for name, enc in self.encoders.items()}

    def fast_convert(self, body: Any, envelope: dict[str, Any] | None = None) -> Any:
        """The instance for a regular, valid body; _SLOW for anything else (never raises)."""
        if type(body) is not dict or body.keys() != self.keyset:
            return _SLOW
        for name in self.float_names:
            v = body[name]
            if type(v) is not float or v - v != 0.0:
                return _SLOW
        kwargs = dict(body)  # never modify `body`: the checked path may still need it as is
        for name, fast in self.fast_others:
            v = fast(body[name])
            if v is _SLOW:
                return _SLOW
            kwargs[name] = v
        if envelope:
            kwargs.update(envelope)
        try:
            return self.cls(**kwargs)
        except Exception:  # noqa: BLE001 - a value out of range: let the checked path say so
            return _SLOW

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


class _Packer(threading.local):
    """One reusable msgpack Packer per thread (msgpack.packb builds a new one per call)."""

    def __init__(self) -> None:
        self.pack = msgpack.Packer(use_bin_type=True).pack  # resets itself after errors too


_PACKER = _Packer()


def encode(
    msg: Message, *, source: str | None = None, seq: int | None = None, sent: float | None = None
) -> bytes:
    """Serialise a message: [version, type, source, seq, stamp, sent, {field: value}].

    `source`, `seq` and `sent` override the envelope fields, so a runtime can stamp a message
    without copying it first (a frozen-dataclass replace costs more than the encoding).
    """
    if seq is not None and not 0 <= seq < 2**63:
        raise WireError(f"seq: {seq!r} is out of range")
    try:
        name, schema = _BY_CLASS[type(msg)]
    except KeyError:
        raise WireError(
            f"cannot encode {type(msg).__name__}: not a tidelink message type"
        ) from None
    data: bytes = _PACKER.pack(
        [
            WIRE_VERSION,
            name,
            msg.source if source is None else source,
            msg.seq if seq is None else seq,
            float(msg.stamp),
            float(msg.sent if sent is None else sent),
            schema.encode(msg),
        ]
    )
    return data


def decode(data: bytes) -> Message:
    """Parse and validate bytes into a message; any problem raises WireError, nothing else."""
    try:
        return _decode(data)
    except WireError:
        raise
    except Exception as exc:  # noqa: BLE001 - the contract: no other exception type escapes
        raise WireError(f"malformed message: {type(exc).__name__}: {exc}") from None


def _decode(data: bytes) -> Message:
    if not isinstance(data, (bytes, bytearray, memoryview)):  # a tuple: faster than a union
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
    if (
        type(source) is str
        and type(seq) is int
        and type(stamp) is float
        and stamp - stamp == 0.0
        and type(sent) is float
        and sent - sent == 0.0
    ):
        fast: Message = schema.fast_convert(
            body, {"source": source, "seq": seq, "stamp": stamp, "sent": sent}
        )
        if fast is not _SLOW:
            return fast
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
    return msgpack.packb([tick, {k: list(v) for k, v in deliveries.items()}])


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
