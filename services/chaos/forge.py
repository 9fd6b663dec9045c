"""Hostile and odd-but-valid payloads, made from a real frame of the stream they go on."""

from __future__ import annotations

import math
from collections.abc import Mapping

from common.messages import Message, fields_of, forge_frame

UNIX_NOW_S = 1.79e9  # a stamp from a clock in Unix time instead of mission time
FUTURE_S = 1.0e6  # how far ahead a future stamp is
OVERSIZED_BYTES = 20 * 1024 * 1024
NOT_MSGPACK = b"\xc1\xc1 this is not MessagePack"
SEQ_JUMP = 2**62
# "hostile": every odd-but-cheap injection at once (one case where the test suite has time
# for one); oversized and flood are cases of their own
HOSTILE = ("malformed", "non_finite", "extreme", "future", "unix", "seq_jump")


def _floats(fields: Mapping[str, object], value: float) -> dict[str, object]:
    """Every top-level float field but the envelope's set to `value`."""
    envelope = ("stamp", "sent", "seq", "source")
    return {
        k: (value if isinstance(v, float) and k not in envelope else v) for k, v in fields.items()
    }


def payloads(mode: str, real: Message) -> list[bytes]:
    """The frames one injection round sends on `real`'s stream (`real`: its newest frame)."""
    kind = type(real).__name__
    f = fields_of(real)
    if mode == "malformed":
        return [NOT_MSGPACK]
    if mode == "oversized":
        return [bytes(OVERSIZED_BYTES)]
    if mode == "non_finite":
        return [forge_frame(kind, _floats(f, math.nan)), forge_frame(kind, _floats(f, math.inf))]
    if mode == "extreme":
        return [forge_frame(kind, _floats(f, 1e300)), forge_frame(kind, _floats(f, -1e300))]
    if mode == "future":
        return [forge_frame(kind, f | {"stamp": real.stamp + FUTURE_S, "seq": real.seq + 1})]
    if mode == "unix":
        return [forge_frame(kind, f | {"stamp": UNIX_NOW_S, "seq": real.seq + 1})]
    if mode == "seq_jump":
        return [forge_frame(kind, f | {"seq": SEQ_JUMP})]
    if mode == "flood":
        return [forge_frame(kind, f | {"seq": real.seq + i}) for i in range(1, 101)]
    if mode == "hostile":
        return [p for m in HOSTILE for p in payloads(m, real)]
    raise ValueError(f"unknown injection {mode!r}")
