"""Scheduled outages of one link: the [start, end) windows in which it delivers nothing."""

from __future__ import annotations

from collections.abc import Iterable

from common.config.network import Outage


class OutageSchedule:
    """The outage windows that apply to one link (by link name/pattern or by service)."""

    def __init__(self, link: str, outages: Iterable[Outage]) -> None:
        self.windows: tuple[tuple[float, float], ...] = tuple(
            sorted((o.start_s, o.end_s) for o in outages if o.applies_to(link))
        )

    def down_at(self, t: float) -> bool:
        """Whether the link is down at time ``t`` (inside some [start, end))."""
        return any(start <= t < end for start, end in self.windows)

    def cuts(self, sent: float, delivered: float) -> bool:
        """Whether a message in flight over [sent, delivered] meets an outage window.

        A message still in flight when a window opens is lost with it (a partition drops what
        is on the wire), so no delivery ever falls inside a window.
        """
        return any(sent < end and delivered >= start for start, end in self.windows)
