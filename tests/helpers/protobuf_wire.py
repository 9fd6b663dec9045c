"""A small protobuf decoder driven by a FileDescriptorSet, for tests (the protobuf package is
not installed here, and the tests should not trust the SDK that encoded the bytes).

`Schemas(fds_bytes).decode(".foxglove.SceneUpdate", data)` gives a dict of field name ->
value: scalars and enums as Python numbers (proto3 defaults when absent), strings, bytes,
nested messages as dicts (None when absent), repeated fields as lists (packed or not).
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

# FieldDescriptorProto.Type (descriptor.proto)
DOUBLE, FLOAT, INT64, UINT64, INT32, FIXED64, FIXED32, BOOL, STRING = range(1, 10)
MESSAGE, BYTES, UINT32, ENUM, SFIXED32, SFIXED64, SINT32, SINT64 = range(11, 19)
REPEATED = 3  # FieldDescriptorProto.Label
VARINT_TYPES = {INT64, UINT64, INT32, BOOL, UINT32, ENUM, SINT32, SINT64}
FIXED = {DOUBLE: "<d", FLOAT: "<f", FIXED64: "<Q", FIXED32: "<I", SFIXED32: "<i", SFIXED64: "<q"}


def _varint(buf: bytes, i: int) -> tuple[int, int]:
    shift = value = 0
    while True:
        b = buf[i]
        i += 1
        value |= (b & 0x7F) << shift
        if not b & 0x80:
            return value, i
        shift += 7
        if shift > 70:
            raise ValueError("varint too long")


def fields(buf: bytes) -> list[tuple[int, int, Any]]:
    """The raw (field number, wire type, value) triples of one message's bytes."""
    out: list[tuple[int, int, Any]] = []
    i = 0
    while i < len(buf):
        key, i = _varint(buf, i)
        num, wt = key >> 3, key & 7
        v: int | bytes
        if wt == 0:
            v, i = _varint(buf, i)
        elif wt == 1:
            v, i = buf[i : i + 8], i + 8
        elif wt == 2:
            n, i = _varint(buf, i)
            v, i = buf[i : i + n], i + n
        elif wt == 5:
            v, i = buf[i : i + 4], i + 4
        else:
            raise ValueError(f"unsupported wire type {wt} (field {num})")
        if i > len(buf):
            raise ValueError("truncated message")
        out.append((num, wt, v))
    return out


@dataclass(frozen=True)
class Field:
    name: str
    number: int
    type: int
    type_name: str
    repeated: bool


def _scalar(ftype: int, raw: Any) -> Any:
    if ftype in FIXED:
        return struct.unpack(FIXED[ftype], raw)[0]
    if ftype == STRING:
        return bytes(raw).decode()
    if ftype == BYTES:
        return bytes(raw)
    v = int(raw)
    if ftype in (INT64, INT32, ENUM) and v >= 1 << 63:
        v -= 1 << 64  # two's complement of a negative int
    if ftype in (SINT32, SINT64):
        v = (v >> 1) ^ -(v & 1)  # zigzag
    if ftype == BOOL:
        return bool(v)
    return v


def _default(f: Field) -> Any:
    if f.repeated:
        return []
    if f.type == MESSAGE:
        return None
    if f.type == STRING:
        return ""
    if f.type == BYTES:
        return b""
    if f.type == BOOL:
        return False
    return 0.0 if f.type in (DOUBLE, FLOAT) else 0


class Schemas:
    """Every message type of a FileDescriptorSet, by full name ('.package.Name')."""

    def __init__(self, fds: bytes) -> None:
        self.messages: dict[str, dict[int, Field]] = {}
        for num, _, file_bytes in fields(fds):
            if num != 1:
                continue
            f = fields(file_bytes)
            package = next((bytes(v).decode() for n, _, v in f if n == 2), "")
            for n, _, msg in f:
                if n == 4:
                    self._add(f".{package}" if package else "", bytes(msg))

    def _add(self, scope: str, desc: bytes) -> None:
        d = fields(desc)
        name = f"{scope}.{next(bytes(v).decode() for n, _, v in d if n == 1)}"
        table: dict[int, Field] = {}
        for n, _, v in d:
            if n == 2:  # FieldDescriptorProto
                fd = {k: val for k, _, val in fields(bytes(v))}
                table[int(fd[3])] = Field(
                    name=bytes(fd[1]).decode(),
                    number=int(fd[3]),
                    type=int(fd[5]),
                    type_name=bytes(fd.get(6, b"")).decode(),
                    repeated=int(fd.get(4, 1)) == REPEATED,
                )
            elif n == 3:  # nested_type
                self._add(name, bytes(v))
        self.messages[name] = table

    def decode(self, type_name: str, data: bytes) -> dict[str, Any]:
        """A message's bytes as a dict (see the module docstring)."""
        table = self.messages[type_name if type_name.startswith(".") else f".{type_name}"]
        out = {f.name: _default(f) for f in table.values()}
        for num, wt, raw in fields(data):
            f = table.get(num)
            if f is None:
                continue  # an unknown field: proto3 skips it
            if f.type == MESSAGE:
                value: Any = self.decode(f.type_name, bytes(raw))
            elif f.repeated and wt == 2 and f.type not in (STRING, BYTES):
                value = self._packed(f.type, bytes(raw))
            else:
                value = _scalar(f.type, raw)
            if f.repeated:
                out[f.name].extend(value if isinstance(value, list) else [value])
            else:
                out[f.name] = value
        return out

    @staticmethod
    def _packed(ftype: int, raw: bytes) -> list[Any]:
        if ftype in FIXED:
            size = struct.calcsize(FIXED[ftype])
            return [_scalar(ftype, raw[i : i + size]) for i in range(0, len(raw), size)]
        if ftype not in VARINT_TYPES:
            raise ValueError(f"type {ftype} cannot be packed")
        values, i = [], 0
        while i < len(raw):
            v, i = _varint(raw, i)
            values.append(_scalar(ftype, v))
        return values
