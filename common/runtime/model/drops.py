"""Messages for a service's inputs lost before its core saw them: counted, and logged sparingly."""

from __future__ import annotations

import logging

from common.config.network import link_name
from common.guard import RateLimitedLog

log = logging.getLogger("tidelink.host")


class InputDrops:
    """Counts per input (source, stream) what never reached the core: over the input's
    max_queued, shed by a full inbox, without or with bad routing, of the wrong type.
    Logged once per input and reason per mission second, so a flood costs a line a second;
    the counts travel in the service's LinkStats (by link name)."""

    def __init__(self, receiver: str) -> None:
        self.receiver = receiver
        self.counts: dict[tuple[str, str], int] = {}
        self._log = RateLimitedLog(log)

    def count(self, source: str, stream: str, n: int, why: str, t: float, detail: str = "") -> None:
        """n messages of input (source, stream) dropped at mission time t; `why` is one of a
        few fixed reasons (it keys the log's rate limit), `detail` free text."""
        key = (source, stream)
        self.counts[key] = self.counts.get(key, 0) + n
        name = link_name(source, stream, self.receiver)
        self._log.warn(
            f"{name}: {why}",
            t,
            "t=%.2f s: %s: dropped %d (%s%s; %d dropped on this input in all)",
            t,
            name,
            n,
            why,
            f": {detail}" if detail else "",
            self.counts[key],
        )

    def by_link(self) -> dict[str, int]:
        """The counts by link name ('source/stream->receiver'), sorted."""
        return {
            link_name(src, stream, self.receiver): n
            for (src, stream), n in sorted(self.counts.items())
        }
