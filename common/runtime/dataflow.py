"""The dataflow of a run: which output feeds which input, validated before anything runs."""

from __future__ import annotations

from dataclasses import dataclass

from common.runtime.core import CoreSpec, InputSpec


class DataflowError(ValueError):
    """The declared inputs and outputs of the cores do not fit together."""


@dataclass(frozen=True)
class Dataflow:
    """Specs of every core and, for each (source, stream), its receivers and their input spec."""

    specs: dict[str, CoreSpec]
    receivers: dict[tuple[str, str], tuple[tuple[str, InputSpec], ...]]

    @classmethod
    def of(cls, specs: list[CoreSpec]) -> Dataflow:
        by_name: dict[str, CoreSpec] = {}
        for s in specs:
            if s.name in by_name:
                raise DataflowError(f"two cores are named {s.name!r}")
            if s.period_s <= 0:
                raise DataflowError(f"{s.name}: period_s must be > 0")
            by_name[s.name] = s
        outputs = {(s.name, o.stream): o for s in specs for o in s.outputs}
        receivers: dict[tuple[str, str], list[tuple[str, InputSpec]]] = {k: [] for k in outputs}
        for s in sorted(specs, key=lambda s: s.name):
            for i in s.inputs:
                out = outputs.get((i.source, i.stream))
                if out is None:
                    raise DataflowError(
                        f"{s.name}: input {i.source}/{i.stream} is not an output of any core"
                    )
                if out.msg_type is not i.msg_type:
                    raise DataflowError(
                        f"{s.name}: input {i.source}/{i.stream} expects {i.msg_type.__name__}"
                        f" but {i.source} publishes {out.msg_type.__name__}"
                    )
                receivers[(i.source, i.stream)].append((s.name, i))
        return cls(by_name, {k: tuple(v) for k, v in receivers.items()})

    @property
    def names(self) -> list[str]:
        return sorted(self.specs)
