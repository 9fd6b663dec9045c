"""Warnings a flood cannot multiply: per reason, one line per interval with the counts."""

from __future__ import annotations

import logging


class RateLimitedLog:
    """Counts every occurrence of each reason; logs the first at once, then at most one line
    per reason per `interval_s`, saying how many occurred so far and how many went unlogged
    since the previous line.

    Time is whatever clock the caller passes (mission time in a core, which has no clock of
    its own; monotonic wall time in a runtime adapter), so the same flood of bad messages
    costs one log line per second however fast it comes. `counts` is what a service reports
    in its statistics.
    """

    def __init__(self, logger: logging.Logger, *, interval_s: float = 1.0) -> None:
        self._log = logger
        self.interval_s = interval_s
        self.counts: dict[str, int] = {}  # reason -> occurrences, logged or not
        self._last: dict[str, float] = {}  # reason -> time of its last logged line
        self._unlogged: dict[str, int] = {}  # reason -> occurrences since that line

    def warn(self, reason: str, t: float, msg: str, *args: object) -> bool:
        """Count one occurrence of `reason` at time t; log `msg % args` unless this reason
        was logged less than interval_s ago. True when a line was written."""
        n = self.counts[reason] = self.counts.get(reason, 0) + 1
        last = self._last.get(reason)
        # a clock that went backwards (a restarted mission clock) logs again at once
        if last is not None and 0.0 <= t - last < self.interval_s:
            self._unlogged[reason] = self._unlogged.get(reason, 0) + 1
            return False
        self._last[reason] = t
        unlogged = self._unlogged.pop(reason, 0)
        more = f", {unlogged} not logged since the last report" if unlogged else ""
        self._log.warning(msg + " [%s: %d so far%s]", *args, reason, n, more)
        return True

    @property
    def total(self) -> int:
        """Occurrences of every reason."""
        return sum(self.counts.values())
