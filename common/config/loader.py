"""Map TOML tables onto frozen config dataclasses by their type hints, with precise errors."""

from __future__ import annotations

import dataclasses
import math
import tomllib
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TypeVar

from common.config.errors import ConfigError, ConfigValueError, KeyPath, format_key
from common.jsonsafe import JsonObject, JsonValue

T = TypeVar("T")


def read_toml(path: str | Path) -> JsonObject:
    """Read a TOML file; anything that keeps it from being read (missing, a directory, not
    UTF-8 text, a syntax error, nesting deeper than the parser's recursion) is a ConfigError
    naming the file."""
    p = Path(path)
    try:
        with p.open("rb") as fh:
            data = fh.read()
    except FileNotFoundError:
        raise ConfigError(str(p), (), "file not found") from None
    except IsADirectoryError:
        raise ConfigError(str(p), (), "is a directory, not a TOML file") from None
    except OSError as exc:
        raise ConfigError(str(p), (), f"cannot be read: {exc.strerror or exc}") from None
    try:
        return tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ConfigError(str(p), (), _not_utf8(data, exc)) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(str(p), (), f"not valid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise ConfigError(str(p), (), "arrays or tables nested too deeply to be read") from None


def _not_utf8(data: bytes, exc: UnicodeDecodeError) -> str:
    """Why bytes that are not UTF-8 are no TOML file, in words a user can act on."""
    if data.startswith((b"\xff\xfe", b"\xfe\xff")):
        return (
            "is UTF-16 text, but a TOML file must be UTF-8: convert it "
            "(e.g. iconv -f UTF-16 -t UTF-8)"
        )
    if b"\x00" in data[:4096]:
        return "is a binary file, not a TOML file (TOML is UTF-8 text)"
    return f"is not UTF-8 text, as a TOML file must be (byte {exc.start}: {exc.reason})"


def read_scenario_toml(path: str | Path, _seen: tuple[Path, ...] = ()) -> JsonObject:
    """A scenario file's tables; with a top-level `extends = "other.toml"` (relative to the
    file) the other scenario's tables with this file's merged over them, table by table (an
    array, such as world.circles, is replaced whole)."""
    p = Path(path).resolve()
    if p in _seen:
        chain = " -> ".join(q.name for q in (*_seen, p))
        raise ConfigError(str(path), ("extends",), f"extends itself ({chain})")
    raw = read_toml(path)
    base = raw.pop("extends", None)
    if base is None:
        return raw
    if not isinstance(base, str):
        raise ConfigError(str(path), ("extends",), f"expected a file name, got {_kind(base)}")
    parent: JsonObject = read_scenario_toml(p.parent / base, (*_seen, p))
    return dict(merge_tables(parent, raw))


def merge_tables(base: Any, override: Any) -> Any:
    """`override` over `base`, table by table (a non-table value replaces whatever was there)."""
    if not isinstance(base, dict) or not isinstance(override, dict):
        return override
    out = dict(base)
    for k, v in override.items():
        out[k] = merge_tables(base[k], v) if k in base else v
    return out


def build(cls: type[T], data: Any, *, file: str = "", path: KeyPath = ()) -> T:
    """Build dataclass `cls` (at key `path` of `file`) from a mapping; bad input raises ConfigError.

    Unknown keys, removed keys (with the reason the table's REMOVED_KEYS gives), wrong types
    and missing keys are found here; a bad value is found by the dataclass's __post_init__,
    whose ConfigValueError names the field below `path`.
    """
    if not isinstance(data, dict):
        raise ConfigError(file, path, f"expected a table, got {_kind(data)}")
    hints = typing.get_type_hints(cls)
    fields = {f.name: f for f in dataclasses.fields(cls) if f.init}  # type: ignore[arg-type]
    # a key the table used to have says why it went (REMOVED_KEYS: key -> reason)
    removed: Mapping[str, str] = getattr(cls, "REMOVED_KEYS", {})
    gone = sorted(set(data) & set(removed))
    if gone:
        exc = ConfigValueError(gone[0], f"was removed: {removed[gone[0]]}")
        raise ConfigError(file, (*path, *exc.key_path), exc.problem)
    unknown = sorted(set(data) - set(fields))
    if unknown:
        raise ConfigError(
            file,
            (*path, unknown[0]),
            f"unknown key (known keys: {', '.join(sorted(fields))})",
        )
    kwargs = {name: _convert(hints[name], v, file, (*path, name)) for name, v in data.items()}
    missing = [
        n
        for n, f in fields.items()
        if n not in kwargs
        and f.default is dataclasses.MISSING
        and f.default_factory is dataclasses.MISSING
    ]
    if missing:
        raise ConfigError(file, (*path, missing[0]), "required key is missing")
    try:
        return cls(**kwargs)
    except ConfigValueError as exc:
        raise ConfigError(file, (*path, *exc.key_path), exc.problem) from None
    except ConfigError:
        raise
    except (ValueError, TypeError) as exc:  # a check that names no field: blame the table
        raise ConfigError(file, path, str(exc)) from None


def _kind(v: Any) -> str:
    return {
        dict: "a table",
        list: "an array",
        str: "a string",
        bool: "a boolean",
        int: "an integer",
        float: "a number",
    }.get(type(v), type(v).__name__)


def _convert(hint: Any, v: Any, file: str, path: KeyPath) -> Any:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if hint is float:
        if type(v) not in (int, float):
            raise ConfigError(file, path, f"expected a number, got {_kind(v)}")
        if not math.isfinite(v):
            raise ConfigError(file, path, "expected a finite number")
        return float(v)
    if hint is int:
        if type(v) is not int:
            raise ConfigError(file, path, f"expected an integer, got {_kind(v)}")
        return v
    if hint is bool:
        if type(v) is not bool:
            raise ConfigError(file, path, f"expected true or false, got {_kind(v)}")
        return v
    if hint is str:
        if type(v) is not str:
            raise ConfigError(file, path, f"expected a string, got {_kind(v)}")
        return v
    if origin is typing.Literal:
        if v not in args:
            raise ConfigError(file, path, f"{v!r} is not one of {', '.join(map(repr, args))}")
        return v
    if origin is tuple:
        if type(v) is not list:
            raise ConfigError(file, path, f"expected an array, got {_kind(v)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], x, file, (*path, i)) for i, x in enumerate(v))
        if len(v) != len(args):
            raise ConfigError(file, path, f"expected an array of {len(args)} values, got {len(v)}")
        return tuple(
            _convert(a, x, file, (*path, i)) for i, (a, x) in enumerate(zip(args, v, strict=True))
        )
    if origin is dict and args and args[0] is str:
        if type(v) is not dict:
            raise ConfigError(file, path, f"expected a table, got {_kind(v)}")
        return {k: _convert(args[1], x, file, (*path, k)) for k, x in v.items()}
    if origin in (types.UnionType, typing.Union):
        errors = []
        for a in args:
            if a is type(None):
                continue
            try:
                return _convert(a, v, file, path)
            except ConfigError as exc:
                errors.append(exc.problem)
        raise ConfigError(file, path, " or ".join(errors))
    if dataclasses.is_dataclass(hint) and isinstance(hint, type):
        return build(hint, v, file=file, path=path)
    raise TypeError(f"config field {format_key(path)}: unsupported type {hint!r}")


def parse_override(text: str) -> tuple[list[str], JsonValue]:
    """Parse a `--set a.b.c=value` override; the value is read as TOML (bare words as strings)."""
    path, sep, raw = text.partition("=")
    if not sep or not path.strip():
        raise ConfigError("--set", (text,), "expected key.path=value")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw
    return path.strip().split("."), value


def apply_override(data: JsonObject, parts: list[str], value: JsonValue) -> None:
    """Set a nested key in a raw TOML mapping, creating tables on the way."""
    node = data
    for p in parts[:-1]:
        nxt = node.setdefault(p, {})
        if not isinstance(nxt, dict):
            raise ConfigError("--set", tuple(parts), f"{p} is not a table")
        node = nxt
    node[parts[-1]] = value
