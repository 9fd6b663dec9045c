"""The one log line for an input a core rejects: its stream, why, and the message's envelope."""

from __future__ import annotations

from common.guard.ratelog import RateLimitedLog
from common.messages import Message


def warn_rejected(log: RateLimitedLog, stream: str, why: str, t: float, msg: Message) -> None:
    """Count a message of `stream` rejected at t for `why` (as '<stream>.<why>') and log it,
    rate-limited, with where it came from (source, stamp, seq)."""
    log.warn(
        f"{stream}.{why}",
        t,
        "t=%.2f s: rejected a %s message (%s): from %r, stamp %.6g s, seq %d",
        t,
        stream,
        why,
        msg.source,
        msg.stamp,
        msg.seq,
    )
