"""The link table (common/link_table.py): two services' LinkStats fill one typed row per link."""

from __future__ import annotations

from common.link_table import LinkTable, dropped
from common.messages import LinkCounters, LinkStats, MeasuredDelay


def _counters(link: str, sent: int) -> LinkCounters:
    return LinkCounters(
        link=link, sent=sent, delivered=sent - 3, dropped_loss=1, dropped_outage=1,
        dropped_queue=1, duplicated=0, delay_p50=0.05, delay_p95=0.08, delay_p99=0.09,
    )  # fmt: skip


def test_the_senders_counters_and_the_receivers_delays_fill_one_row_by_link_name() -> None:
    table = LinkTable()
    measured = MeasuredDelay(
        link="b/x->c", delivered=7, delay_p50=0.06, delay_p95=0.1, delay_max=0.2
    )
    table.see(LinkStats(stamp=1.0, links=(_counters("b/x->c", 10), _counters("a/y->b", 5))))
    table.see(LinkStats(stamp=1.0, links=(), measured=(measured,)))
    rows = table.rows()
    assert [r.link for r in rows] == ["a/y->b", "b/x->c"]
    assert rows[0].measured is None  # its receiver has not said yet
    assert rows[1].counters is not None and rows[1].measured == measured
    assert dropped(rows[1].counters) == 3
    # a later statistics of the same sender replaces its part, the receiver's stays
    table.see(LinkStats(stamp=2.0, links=(_counters("b/x->c", 20),)))
    later = table.rows()[1]
    assert later.counters is not None and later.counters.sent == 20
    assert later.measured == measured
