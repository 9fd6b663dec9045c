"""Print the config reference (every scenario key, its type and default) as Markdown tables."""

from __future__ import annotations

import dataclasses
import types
import typing
from typing import Any

from common.config.fleet import SECTIONS
from common.config.scenario import Scenario


def _type_name(hint: Any) -> str:
    origin = typing.get_origin(hint)
    args = typing.get_args(hint)
    if origin is typing.Literal:
        return " \\| ".join(f'"{a}"' for a in args)
    if origin is tuple:
        inner = args[0]
        if dataclasses.is_dataclass(inner) and isinstance(inner, type):
            return f"array of tables ({inner.__name__})"
        return f"array of {_type_name(inner)}"
    if origin is dict:
        return f"table of {' or '.join(_type_name(a) for a in typing.get_args(args[1]))}"
    if origin in (types.UnionType, typing.Union) and type(None) in args:
        # an optional key: the table's cell must not carry a bare "|"
        kept = [a for a in args if a is not type(None)]
        return " or ".join(_type_name(a) for a in kept) + " (optional)"
    if isinstance(hint, type):
        return {float: "number", int: "integer", str: "string", bool: "bool"}.get(
            hint, hint.__name__
        )
    return str(hint)


def _default(f: dataclasses.Field[Any]) -> str:
    if f.default is not dataclasses.MISSING:
        v = f.default
    elif f.default_factory is not dataclasses.MISSING:
        v = f.default_factory()
    else:
        return "(required)"
    if dataclasses.is_dataclass(v):
        return "(table)"
    if isinstance(v, str):
        return f'"{v}"'
    if isinstance(v, bool):
        return str(v).lower()
    if isinstance(v, tuple):
        return "[]" if not v else str(list(v))
    return repr(v)


def rows(cls: type, prefix: str = "") -> list[tuple[str, str, str]]:
    """(key path, type, default) of every key under a config dataclass, depth first."""
    out: list[tuple[str, str, str]] = []
    hints = typing.get_type_hints(cls)
    for f in dataclasses.fields(cls):
        if not f.init:
            continue
        hint = hints[f.name]
        key = f"{prefix}{f.name}"
        if dataclasses.is_dataclass(hint) and isinstance(hint, type):
            out.extend(rows(hint, key + "."))
            continue
        if typing.get_origin(hint) is tuple and dataclasses.is_dataclass(typing.get_args(hint)[0]):
            out.append((key, _type_name(hint), _default(f)))
            out.extend(rows(typing.get_args(hint)[0], key + "[]."))
            continue
        out.append((key, _type_name(hint), _default(f)))
    return out


def markdown() -> str:
    """The whole reference, one table per scenario section."""
    parts = []
    for f in dataclasses.fields(Scenario):
        section = typing.get_type_hints(Scenario)[f.name]
        if typing.get_origin(section) is tuple:  # [[vehicles]]: an array of tables
            parts.extend(_fleet_rows(f.name, typing.get_args(section)[0]))
            continue
        doc = (section.__doc__ or "").strip().splitlines()[0]
        parts.append(f"#### `[{f.name}]` — {doc}\n\n| key | type | default |\n|---|---|---|")
        parts.extend(f"| `{f.name}.{k}` | {t} | `{d}` |" for k, t, d in rows(section))
        parts.append("")
    return "\n".join(parts)


def _fleet_rows(name: str, entry: type) -> list[str]:
    """The `[[vehicles]]` table: id, start and goal, and the sections an entry overrides."""
    doc = (entry.__doc__ or "").strip().splitlines()[0]
    out = [f"#### `[[{name}]]` — {doc}\n\n| key | type | default |\n|---|---|---|"]
    for k, t, d in rows(entry):
        section = k.split(".")[0]
        if section in SECTIONS:
            if k == section + "." + next(iter(rows(SECTIONS[section])))[0]:
                out.append(
                    f"| `{name}[].{section}` | table: any `[{section}]` key, over the "
                    f"scenario's | `{{}}` |"
                )
            continue
        out.append(f"| `{name}[].{k}` | {t} | `{d}` |")
    out.append("")
    return out


if __name__ == "__main__":
    print(markdown())
