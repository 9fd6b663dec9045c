"""A run's link table: one typed row per link, filled by two services' LinkStats (the sender's
counters and modelled delays, the receiver's measured delays); metrics.json, the monitor and
Foxglove each print it with their own column names."""

from __future__ import annotations

from dataclasses import dataclass

from common.messages import LinkCounters, LinkStats, MeasuredDelay


@dataclass
class LinkRow:
    """One link ("source/stream->receiver"): what its sender counted (None until its sender's
    statistics came) and what its receiver measured (None until the receiver's came)."""

    link: str
    counters: LinkCounters | None = None  # the sender's: counts, bytes, modelled delays (s)
    measured: MeasuredDelay | None = None  # the receiver's: hand-over to its core minus sent (s)


def dropped(c: LinkCounters) -> int:
    """Every message a link's model dropped: by loss, in an outage, off a full queue."""
    return c.dropped_loss + c.dropped_outage + c.dropped_queue


class LinkTable:
    """Every link's row, updated by each LinkStats seen (a later one replaces its part)."""

    def __init__(self) -> None:
        self._rows: dict[str, LinkRow] = {}

    def see(self, stats: LinkStats) -> None:
        """Take one service's statistics: its outgoing links' counters, its measured delays."""
        for c in stats.links:
            self._row(c.link).counters = c
        for d in stats.measured:
            self._row(d.link).measured = d

    def rows(self) -> list[LinkRow]:
        """Every row, by link name."""
        return [self._rows[k] for k in sorted(self._rows)]

    def _row(self, link: str) -> LinkRow:
        row = self._rows.get(link)
        if row is None:
            row = self._rows[link] = LinkRow(link)
        return row
