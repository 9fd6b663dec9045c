"""A bounded Inbox (issue 14, defect 8): beyond max_pending waiting events it sheds the oldest
samples, never a liveliness event nor a sample whose key it must keep, and says what it shed;
without max_pending it never drops anything."""

from __future__ import annotations

import queue
import threading
from typing import Any

from common.bus import Inbox, Keys, Liveliness, Received
from common.bus.bus import QUIET_BATCH, RawFrame
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


class _WatchedQueue(queue.SimpleQueue[Any]):
    """A queue that says when a reader starts waiting on it."""

    def __init__(self) -> None:
        self.waiting = threading.Event()

    def get(self, block: bool = True, timeout: float | None = None) -> Any:
        self.waiting.set()
        return super().get(block, timeout)


def _waiting_get(inbox: Inbox, fifo: _WatchedQueue, *, data: bool) -> list[Received]:
    """Events a reader blocked in get(data=...) took: started, then once it waits."""
    got: list[Received] = []

    def read() -> None:
        for _ in range(2):
            ev = inbox.get(timeout=30.0, data=data)
            assert isinstance(ev, Received)
            got.append(ev)

    reader = threading.Thread(target=read)
    reader.start()
    assert fifo.waiting.wait(30.0)  # the reader is inside its wait
    inbox.on_quiet_sample(_nav(1))  # data arrives quietly...
    inbox._q.put(_tick(1))  # ...then the clock's tick
    reader.join(30.0)
    assert not reader.is_alive()
    return got


def test_a_quiet_sample_does_not_end_a_wait_for_the_clock_but_comes_first_after_it() -> None:
    # a lockstep service waiting for its tick is not woken by each message arriving meanwhile
    fifo = _WatchedQueue()
    got = _waiting_get(Inbox(fifo=fifo), fifo, data=False)
    assert [type(e.msg).__name__ for e in got] == ["Tick", "NavFix"]


def test_a_quiet_sample_ends_a_wait_for_data() -> None:
    fifo = _WatchedQueue()
    got = _waiting_get(Inbox(fifo=fifo), fifo, data=True)
    assert [type(e.msg).__name__ for e in got] == ["NavFix", "Tick"]


def test_quiet_samples_are_counted_detached_and_kept_in_order() -> None:
    inbox = Inbox()
    for seq in range(1, 4):
        inbox.on_quiet_sample(_nav(seq))
    assert inbox.pending() == 3
    inbox.detach()
    assert [e.msg.seq for e in _drain(inbox) if isinstance(e, Received)] == [1, 2, 3]


def test_a_batch_of_quiet_samples_ends_any_wait() -> None:
    # a flood on a data key is worked off as it comes, not piled up until the next tick
    fifo = _WatchedQueue()
    inbox = Inbox(fifo=fifo)
    got: list[Received | Liveliness | None] = []
    reader = threading.Thread(target=lambda: got.append(inbox.get(timeout=30.0, data=False)))
    reader.start()
    assert fifo.waiting.wait(30.0)
    for seq in range(1, QUIET_BATCH + 1):
        inbox.on_quiet_sample(_nav(seq))
    reader.join(30.0)
    assert not reader.is_alive()
    first = got[0]
    assert isinstance(first, Received) and isinstance(first.msg, NavFix) and first.msg.seq == 1
    assert inbox.pending() == QUIET_BATCH - 1  # the rest, taken next without waiting
