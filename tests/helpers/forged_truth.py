"""Forged truth in tests: the real truth states after which a test puts its forgeries."""

from __future__ import annotations

from common.bus import Received
from common.messages import TruthState

FORGED_SEQ = 2**62  # the seq forgeries carry, so a test never takes its own for real ones


def real_truth_due(ev: object, every: int) -> TruthState | None:
    """The vehicle's own truth state when it is every `every`-th one (a cue to forge after
    it); None for anything else, forgeries included."""
    if not isinstance(ev, Received) or not isinstance(ev.msg, TruthState):
        return None
    real = ev.msg
    if real.source != "vehicle" or real.seq >= FORGED_SEQ or real.seq % every:
        return None
    return real
