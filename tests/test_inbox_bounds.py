"""A bounded Inbox (issue 14, defect 8): beyond max_pending waiting events it sheds the oldest
samples, never a liveliness event nor a sample whose key it must keep, and says what it shed;
without max_pending it never drops anything."""

from __future__ import annotations

from common.bus import Inbox, Keys, Liveliness, Received
from common.bus.bus import RawFrame
from common.messages import NavFix, Tick, encode

KEYS = Keys("r", "v")
NAV = KEYS.stream("sensor", "nav")
TICK = KEYS.tick(["estimator"])


def _nav(seq: int) -> RawFrame:
    msg = NavFix(
        stamp=0.0, seq=seq, x=0, y=0, heading=0, speed=0, std_xy=0, std_heading=0, std_speed=0
    )
    return RawFrame(NAV, encode(msg), None)


def _tick(n: int) -> RawFrame:
    return RawFrame(TICK, encode(Tick(stamp=0.0, tick=n, time_us=n)), None)


def _drain(inbox: Inbox) -> list[Received | Liveliness]:
    out = []
    while (ev := inbox.get(timeout=0)) is not None:
        out.append(ev)
    return out


def test_a_bounded_inbox_sheds_the_oldest_samples_but_never_ticks_or_liveliness() -> None:
    shed: list[tuple[str, int]] = []
    inbox = Inbox(max_pending=100, keep=KEYS.is_tick, on_shed=lambda k, n: shed.append((k, n)))
    alive = Liveliness(KEYS.alive("runtime"), True)
    inbox._q.put(_tick(1))
    inbox._q.put(alive)
    for seq in range(1, 1001):
        inbox._q.put(_nav(seq))
    inbox._q.put(_tick(2))
    got = _drain(inbox)
    # 1003 waiting: down to half of max_pending (50), the three precious ones among them
    assert shed == [(NAV, 953)] and inbox.shed == {NAV: 953}
    ticks = [e.msg.tick for e in got if isinstance(e, Received) and isinstance(e.msg, Tick)]
    navs = [e.msg.seq for e in got if isinstance(e, Received) and isinstance(e.msg, NavFix)]
    assert ticks == [1, 2] and alive in got
    assert navs == list(range(954, 1001))  # the newest survive, in order
    assert [type(e.msg).__name__ if isinstance(e, Received) else "alive" for e in got][:2] == [
        "Tick",
        "alive",
    ]


def test_an_unbounded_inbox_keeps_everything() -> None:
    inbox = Inbox()
    for seq in range(1, 5001):
        inbox._q.put(_nav(seq))
    assert [e.msg.seq for e in _drain(inbox) if isinstance(e, Received)] == list(range(1, 5001))
    assert inbox.shed == {}


def test_what_a_shed_kept_is_detached_in_order_when_the_bus_closes() -> None:
    inbox = Inbox(max_pending=10)
    for seq in range(1, 31):
        inbox._q.put(_nav(seq))
    first = inbox.get(timeout=0)  # sheds down to 5: seqs 26..30, takes 26
    assert isinstance(first, Received) and first.msg.seq == 26
    inbox._q.put(_nav(31))
    inbox.detach()
    assert inbox.pending() == 5
    assert [e.msg.seq for e in _drain(inbox) if isinstance(e, Received)] == [27, 28, 29, 30, 31]
