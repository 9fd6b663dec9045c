"""Codec properties: round trips, decode is total (WireError or a Message), errors say what.

Strategies are derived from each message class's type hints (so a new field is covered
automatically), with per-type overrides for the fields that have a valid range.
"""

from __future__ import annotations

import math
import typing
from collections.abc import Callable
from typing import Any

import msgpack
import msgspec
import pytest
from helpers.samples import one_of_each, variants
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from common.messages import (
    MAX_SEQUENCE_LEN,
    MESSAGE_TYPES,
    SEQUENCE_STEP_MAX_MS,
    SEQUENCE_STEP_MIN_MS,
    WIRE_VERSION,
    Detection,
    Frame,
    LinkCounters,
    LinkStats,
    MeasuredDelay,
    Message,
    NavFix,
    Odometry,
    PathAck,
    PathMsg,
    PositionFix,
    RunEnd,
    StateEstimate,
    Tick,
    TickAck,
    Track,
    VehicleStatus,
    VelocityCommand,
    WireError,
    WireRecord,
    decode,
    decode_own,
    encode,
    replace,
)

S = st.SearchStrategy
FINITE = st.floats(allow_nan=False, allow_infinity=False)
NONNEG = st.floats(min_value=0.0, allow_nan=False, allow_infinity=False)
POSITIVE = st.floats(min_value=0.0, exclude_min=True, allow_nan=False, allow_infinity=False)
INT64 = st.integers(-(2**63), 2**63 - 1)  # msgpack's signed range
COUNT = st.integers(0, 2**63 - 1)
TEXT = st.text(max_size=12)

PROPS = settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow])


@st.composite
def _cov(draw: st.DrawFn, n: int) -> tuple[float, ...]:
    """An n x n row-major matrix with a non-negative diagonal (what the wire requires)."""
    diag = draw(st.lists(NONNEG, min_size=n, max_size=n))
    off = draw(st.lists(FINITE, min_size=n * n, max_size=n * n))
    return tuple(diag[i // n] if i // n == i % n else off[i] for i in range(n * n))


# Fields with a valid range, per class; everything else comes from the type hint.
OVERRIDES: dict[type, dict[str, S[Any]]] = {
    Message: {"stamp": FINITE, "sent": FINITE, "seq": COUNT, "source": TEXT},
    NavFix: {"std_xy": NONNEG, "std_heading": NONNEG, "std_speed": NONNEG},
    Odometry: {
        "std_heading": NONNEG,
        "std_yaw_rate": NONNEG,
        "std_water_speed": NONNEG,
        "std_velocity": NONNEG,
    },
    PositionFix: {"std_xy": NONNEG},
    Detection: {"id": COUNT, "radius": NONNEG, "std_xy": NONNEG, "std_radius": NONNEG},
    StateEstimate: {
        "covariance": _cov(5),
        "predicted_s": NONNEG,
        "current_std": NONNEG,
        "sway_std": NONNEG,
    },
    Track: {"id": COUNT, "radius": NONNEG, "covariance": _cov(6)},
    VelocityCommand: {"path_id": COUNT},
    PathAck: {"path_id": COUNT, "since": NONNEG},
    VehicleStatus: {
        "command_age": NONNEG,
        "commands_applied": COUNT,
        "commands_rejected": COUNT,
        "commands_clamped": COUNT,
        "rejected_by_reason": st.dictionaries(TEXT, COUNT, max_size=5),
        "delay_jitter_s": NONNEG,
        "delay_samples": COUNT,
    },
    LinkCounters: {
        **{
            k: COUNT
            for k in (
                "sent",
                "delivered",
                "dropped_loss",
                "dropped_outage",
                "dropped_queue",
                "bytes_sent",
            )
        },
        "duplicated": COUNT,
        "delay_p50": NONNEG,
        "delay_p95": NONNEG,
        "delay_p99": NONNEG,
    },
    MeasuredDelay: {
        "delivered": COUNT,
        **{k: NONNEG for k in ("delay_p50", "delay_p95", "delay_max")},
    },
    LinkStats: {
        k: st.dictionaries(TEXT, COUNT, max_size=5)
        for k in ("inputs_dropped", "inputs_rejected", "resets", "counters")
    },
    Tick: {"tick": COUNT, "time_us": COUNT},
    Frame: {
        "source": st.text(min_size=1, max_size=12),
        "stream": st.text(min_size=1, max_size=12),
        "seq": st.integers(1, 2**62),
    },
    TickAck: {"tick": COUNT, "next_us": COUNT, "service": st.text(min_size=1, max_size=12)},
    RunEnd: {"ticks": COUNT},
}


def strategy_for_hint(hint: Any) -> S[Any]:
    """A strategy of valid values for one field type (float, int, str, bool, Literal, ...)."""
    simple: dict[Any, S[Any]] = {
        float: FINITE,
        int: INT64,
        str: TEXT,
        bool: st.booleans(),
        bytes: st.binary(max_size=32),
    }
    if hint in simple:
        return simple[hint]
    origin, args = typing.get_origin(hint), typing.get_args(hint)
    if origin is typing.Literal:
        return st.sampled_from(args)
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        return st.lists(strategy_for_hint(args[0]), max_size=6).map(tuple)
    if origin is dict and args == (str, int):
        return st.dictionaries(TEXT, INT64, max_size=4)
    if isinstance(hint, type) and issubclass(hint, WireRecord):
        return strategy_for_class(hint)
    raise TypeError(f"no strategy for field type {hint!r}")


def strategy_for_class(cls: type) -> S[Any]:
    """st.builds over the record's fields, with the class's (and its bases') overrides."""
    if cls is PathMsg:
        return path_msgs()
    if cls is VelocityCommand:
        return velocity_commands()
    hints = typing.get_type_hints(cls)
    over: dict[str, S[Any]] = {}
    for base in reversed(cls.__mro__):
        over.update(OVERRIDES.get(base, {}))
    kwargs = {
        f.name: over[f.name] if f.name in over else strategy_for_hint(hints[f.name])
        for f in msgspec.structs.fields(cls)
    }
    return st.builds(cls, **kwargs)


@st.composite
def path_msgs(draw: st.DrawFn) -> PathMsg:
    """A PathMsg whose counts agree: n control points, n weights > 0, n + degree + 1 knots."""
    env = {k: draw(v) for k, v in OVERRIDES[Message].items()}
    path_id = draw(COUNT)
    if draw(st.booleans()):  # NO_PATH: only the status and reason are meaningful
        return PathMsg(
            **env,
            path_id=path_id,
            status="NO_PATH",
            reason=draw(TEXT),
            degree=0,
            control_points=(),
            weights=(),
            knots=(),
            waypoints=(),
            length=0.0,
            f_l=0.0,
            max_curvature=0.0,
            v_ref=0.0,
        )
    degree = draw(st.integers(1, 5))
    n = draw(st.integers(degree + 1, degree + 6))
    knots = sorted(draw(st.lists(FINITE, min_size=n + degree + 1, max_size=n + degree + 1)))
    n_way = draw(st.integers(0, 6))
    return PathMsg(
        **env,
        path_id=path_id,
        status="OK",
        reason="",
        degree=degree,
        control_points=tuple(draw(st.lists(FINITE, min_size=2 * n, max_size=2 * n))),
        weights=tuple(draw(st.lists(POSITIVE, min_size=n, max_size=n))),
        knots=tuple(knots),
        waypoints=tuple(draw(st.lists(FINITE, min_size=2 * n_way, max_size=2 * n_way))),
        length=draw(NONNEG),
        f_l=draw(NONNEG),
        max_curvature=draw(NONNEG),
        v_ref=draw(NONNEG),
    )


ENTRY = st.integers(-100_000, 100_000)  # a future entry, in thousandths of m/s or rad/s


@st.composite
def velocity_commands(draw: st.DrawFn) -> VelocityCommand:
    """A single command, or one with n future entries at a step in the wire's bounds."""
    env = {k: draw(v) for k, v in OVERRIDES[Message].items()}
    n = draw(st.integers(0, 6))
    step = st.integers(SEQUENCE_STEP_MIN_MS, SEQUENCE_STEP_MAX_MS) if n else st.just(0)
    return VelocityCommand(
        **env,
        v=draw(FINITE),
        w=draw(FINITE),
        path_id=draw(COUNT),
        controller=draw(TEXT),
        step_ms=draw(step),
        v_next_mmps=tuple(draw(st.lists(ENTRY, min_size=n, max_size=n))),
        w_next_mradps=tuple(draw(st.lists(ENTRY, min_size=n, max_size=n))),
    )


BY_TYPE: dict[type[Message], S[Any]] = {cls: strategy_for_class(cls) for cls in MESSAGE_TYPES}
ANY_MESSAGE: S[Message] = st.one_of(list(BY_TYPE.values()))


# --- round trip ---------------------------------------------------------------------------------


@pytest.mark.parametrize("cls", MESSAGE_TYPES, ids=lambda c: c.__name__)
@PROPS
@given(data=st.data())
def test_round_trip_of_every_type(cls: type[Message], data: st.DataObject) -> None:
    msg = data.draw(BY_TYPE[cls])
    wire = encode(msg)
    back = decode(wire)
    assert type(back) is cls
    assert back == msg
    # canonical: re-encoding gives the same bytes (so -0.0, key order, ints vs floats survive)
    assert encode(back) == wire


# --- decode is total: a Message or WireError, never anything else -------------------------------


def _decode_total(data: bytes) -> Message | WireError:
    try:
        msg = decode(data)
    except WireError as exc:
        assert str(exc), "a WireError must say what is wrong"
        return exc
    assert isinstance(msg, Message)
    assert type(msg) in MESSAGE_TYPES
    return msg


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=600))
def test_decode_of_arbitrary_bytes_raises_only_wire_error(data: bytes) -> None:
    _decode_total(data)


Mutation = Callable[[bytearray], None]
PINNED = [*one_of_each(), *variants().values()]


@st.composite
def _mutation(draw: st.DrawFn, size: int) -> tuple[str, int, int]:
    kind = draw(st.sampled_from(["flip", "set", "insert", "delete", "truncate"]))
    pos = draw(st.integers(0, max(0, size - 1)))
    return kind, pos, draw(st.integers(0, 255))


def _apply(buf: bytearray, kind: str, pos: int, val: int) -> None:
    if kind == "flip":
        buf[pos] ^= 1 << (val % 8)
    elif kind == "set":
        buf[pos] = val
    elif kind == "insert":
        buf.insert(pos, val)
    elif kind == "delete":
        del buf[pos]
    else:
        del buf[pos:]


@st.composite
def mutated_messages(draw: st.DrawFn) -> bytes:
    """A valid encoded message with 1-4 flipped/overwritten/inserted/deleted bytes or truncated."""
    buf = bytearray(encode(draw(ANY_MESSAGE | st.sampled_from(PINNED))))
    for _ in range(draw(st.integers(1, 4))):
        if buf:
            _apply(buf, *draw(_mutation(len(buf))))
    return bytes(buf)


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(mutated_messages())
def test_decode_of_mutated_messages_raises_only_wire_error(data: bytes) -> None:
    _decode_total(data)


# Any msgpack value (what a buggy or hostile peer could send that still parses as msgpack).
MSGPACK_VALUES: S[Any] = st.recursive(
    st.none() | st.booleans() | INT64 | st.floats() | TEXT | st.binary(max_size=8),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(TEXT, inner, max_size=4),
    max_leaves=12,
)


@st.composite
def wellformed_envelopes_with_junk(draw: st.DrawFn) -> bytes:
    """A valid envelope and type name whose body has the right keys but arbitrary values."""
    msg = draw(st.sampled_from(PINNED))
    frame = msgpack.unpackb(encode(msg))
    body = frame[1]
    for key in draw(st.lists(st.sampled_from(sorted(body)), min_size=1, max_size=3)):
        body[key] = draw(MSGPACK_VALUES)
    if draw(st.booleans()):
        frame[0] = draw(MSGPACK_VALUES)
    return bytes(msgpack.packb(frame, use_bin_type=True))


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(wellformed_envelopes_with_junk())
def test_decode_of_junk_field_values_raises_only_wire_error(data: bytes) -> None:
    _decode_total(data)


@settings(max_examples=200, deadline=None)
@given(MSGPACK_VALUES)
def test_decode_of_arbitrary_msgpack_raises_only_wire_error(value: Any) -> None:
    _decode_total(bytes(msgpack.packb(value, use_bin_type=True)))


# --- each kind of error says what is wrong ------------------------------------------------------


def _nav_frame() -> list[Any]:
    """[version, {type, stamp, source, seq, sent, fields...}] of the sample NavFix."""
    nav = one_of_each()[0]
    assert isinstance(nav, NavFix)
    frame: list[Any] = msgpack.unpackb(encode(nav))
    return frame


def _packed(frame: Any) -> bytes:
    return bytes(msgpack.packb(frame, use_bin_type=True))


def _with_version(value: Any) -> bytes:
    frame = _nav_frame()
    frame[0] = value
    return _packed(frame)


def _with_field(name: str, value: Any) -> bytes:
    frame = _nav_frame()
    frame[1][name] = value
    return _packed(frame)


def _without_field(name: str) -> bytes:
    frame = _nav_frame()
    del frame[1][name]
    return _packed(frame)


def _track_with_cov(cov: list[float]) -> bytes:
    frame: list[Any] = msgpack.unpackb(encode(one_of_each()[3]))
    frame[1]["tracks"][0]["covariance"] = cov
    return _packed(frame)


def _sequence_with(**fields: Any) -> bytes:
    """The pinned command with future entries, some fields replaced (as a hostile peer might)."""
    frame: list[Any] = msgpack.unpackb(encode(variants()["VelocityCommand+sequence"]))
    frame[1].update(fields)
    return _packed(frame)


_VALID = encode(one_of_each()[0])
_HUGE = 10**6
# A sequence's entry times are stamp + k * step_s: they cannot be out of order by construction;
# what a peer can get wrong is the step, the lengths and the entries themselves.
SEQUENCE_CASES: list[tuple[str, bytes, list[str]]] = [
    (
        "a million entries",
        _sequence_with(v_next_mmps=[1500] * _HUGE, w_next_mradps=[0] * _HUGE),
        ["VelocityCommand.v_next_mmps", f"length <= {MAX_SEQUENCE_LEN}"],
    ),
    (
        "nan entry",
        _sequence_with(w_next_mradps=[0, math.nan, 5]),
        ["VelocityCommand.w_next_mradps[1]", "expected `int`", "float"],
    ),
    (
        "entry out of range",
        _sequence_with(v_next_mmps=[10**7, 0, 0]),
        ["VelocityCommand.v_next_mmps[0]", "<= 100000"],
    ),
    ("zero step", _sequence_with(step_ms=0), ["step_ms", "out of range", ">= 1"]),
    ("negative step", _sequence_with(step_ms=-100), ["step_ms", "-100", "out of range"]),
    ("nan step", _sequence_with(step_ms=math.nan), ["step_ms", "expected `int`", "float"]),
    ("step of an hour", _sequence_with(step_ms=3_600_000), ["step_ms", "<= 10000"]),
    (
        "unequal lengths",
        _sequence_with(w_next_mradps=[0]),
        ["w_next_mradps", "expected 3", "got 1"],
    ),
    (
        "step without entries",
        _sequence_with(v_next_mmps=[], w_next_mradps=[]),
        ["step_ms", "without future entries"],
    ),
]
ERROR_CASES: list[tuple[str, bytes, list[str]]] = [
    ("unknown type", _with_field("type", "Teleport"), ["unknown message type", "'Teleport'"]),
    ("no type", _without_field("type"), ["no message type"]),
    (
        "wrong version",
        _with_version(WIRE_VERSION + 1),
        ["wrong wire version", str(WIRE_VERSION + 1), f"speaks {WIRE_VERSION}"],
    ),
    ("version as float", _with_version(float(WIRE_VERSION)), ["wrong wire version"]),
    ("missing field", _without_field("heading"), ["NavFix", "missing required field", "heading"]),
    ("extra field", _with_field("depth", 3.0), ["NavFix", "unknown field", "depth"]),
    ("wrong type", _with_field("x", "ten"), ["NavFix.x", "expected `float`", "str"]),
    ("bool for a float", _with_field("speed", True), ["NavFix.speed", "expected `float`", "bool"]),
    ("nan field", _with_field("y", math.nan), ["NavFix", "y: nan", "not a finite number"]),
    ("inf field", _with_field("y", math.inf), ["NavFix", "y: inf", "not a finite number"]),
    ("inf stamp", _with_field("stamp", -math.inf), ["stamp: -inf", "not a finite number"]),
    ("negative std", _with_field("std_xy", -0.5), ["std_xy", "-0.5", "out of range", ">= 0"]),
    ("negative seq", _with_field("seq", -1), ["seq", "-1", "out of range", ">= 0"]),
    ("seq as float", _with_field("seq", 1.5), ["NavFix.seq", "expected `int`", "float"]),
    ("source not text", _with_field("source", 7), ["NavFix.source", "expected `str`", "int"]),
    ("truncated", _VALID[:-5], ["truncated or invalid msgpack"]),
    ("trailing bytes", _VALID + b"\x00", ["trailing bytes"]),
    ("empty", b"", ["empty payload"]),
    ("not an envelope", _packed([WIRE_VERSION]), ["not a tidelink envelope", "2-element"]),
    ("not an array", _packed({"type": "NavFix"}), ["not a tidelink envelope"]),
    ("body not a map", _packed([WIRE_VERSION, [1, 2]]), ["expected a map of fields", "an array"]),
    (
        "short covariance",
        _track_with_cov([1.0] * 35),
        ["ObstacleTracks.tracks[0]", "track.covariance", "36", "got 35"],
    ),
    (
        "negative variance",
        _track_with_cov([-1.0] + [0.0] * 35),
        ["track.covariance", "diagonal entry 0", "negative"],
    ),
]


@pytest.mark.parametrize(
    ("what", "data", "needles"),
    ERROR_CASES + SEQUENCE_CASES,
    ids=[c[0] for c in ERROR_CASES + SEQUENCE_CASES],
)
def test_decode_errors_say_what_is_wrong(what: str, data: bytes, needles: list[str]) -> None:
    with pytest.raises(WireError) as info:
        decode(data)
    text = str(info.value)
    for needle in needles:
        assert needle in text, f"{what}: {needle!r} not in {text!r}"


def test_decode_rejects_what_is_not_bytes() -> None:
    with pytest.raises(WireError, match="expected bytes, got str"):
        decode("hello")  # type: ignore[arg-type]


def test_encode_rejects_a_foreign_class() -> None:
    class Alien(Message, frozen=True, kw_only=True):
        """Not registered in MESSAGE_TYPES."""

    with pytest.raises(WireError, match="cannot encode Alien"):
        encode(Alien(stamp=0.0))


def test_the_valid_frame_used_above_decodes() -> None:
    # the error cases differ from a valid message only in what they name
    assert decode(_packed(_nav_frame())) == one_of_each()[0]


# --- stamping and decoding what this process encoded (the inproc runtime's wire) ----------------

SAMPLES = [*one_of_each(), *variants().values()]


class _NoEnvelope:
    """A message's fields for `validate`, failing on the envelope's (source, seq, sent)."""

    def __init__(self, msg: Message) -> None:
        self._msg = msg

    def __getattr__(self, name: str) -> object:
        assert name not in ("source", "seq", "sent"), f"validate read the envelope's {name}"
        return getattr(self._msg, name)


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_validate_never_reads_the_envelope(msg: Message) -> None:
    # what lets encode stamp a checked message with only the shared checks (codec._stamped)
    type(msg).validate(_NoEnvelope(msg))  # type: ignore[arg-type]


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
@pytest.mark.parametrize(
    "envelope",
    [
        {"seq": -1},
        {"seq": 2**63},
        {"sent": math.nan},
        {"sent": -math.inf, "seq": 4},
        {"source": "x", "seq": 7, "sent": 1.5},
    ],
    ids=str,
)
def test_encode_stamps_an_envelope_as_replace_would(msg: Message, envelope: dict[str, Any]) -> None:
    try:
        expected: bytes | str = encode(replace(msg, **envelope))
    except WireError as exc:
        expected = str(exc)
    try:
        got: bytes | str = encode(msg, **envelope)
    except WireError as exc:
        got = str(exc)
    assert got == expected


@pytest.mark.parametrize("msg", SAMPLES, ids=lambda m: type(m).__name__)
def test_decode_own_gives_what_decode_gives(msg: Message) -> None:
    wire = encode(msg)
    assert decode_own(wire) == decode(wire) == msg


def test_decode_own_leaves_the_checks_on() -> None:
    with pytest.raises(WireError):
        decode_own(b"\x92\x0c")  # a refused frame: the checks come back on all the same
    with pytest.raises(WireError, match="std_xy"):
        NavFix(
            stamp=0.0,
            x=0.0,
            y=0.0,
            heading=0.0,
            speed=0.0,
            std_xy=-1.0,
            std_heading=0.0,
            std_speed=0.0,
        )
