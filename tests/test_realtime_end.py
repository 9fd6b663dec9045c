"""The end of a realtime run: how long the driver waits for the services' final statistics."""

from __future__ import annotations

from common.runtime.distributed.realtime_driver import GoneGrace


def test_each_services_grace_counts_from_its_own_going_all_at_once() -> None:
    names = {"sensor", "estimator", "planner", "vehicle"}
    grace = GoneGrace(names, grace_s=0.5)
    assert not grace.over(names, now=10.0)  # all alive
    assert not grace.over(set(), now=10.2)  # all gone at 10.2: one grace for all of them
    assert not grace.over(set(), now=10.7)
    assert grace.over(set(), now=10.71)  # not 4 x 0.5 s later, one after another


def test_one_still_alive_holds_the_end_and_its_grace_starts_when_it_goes() -> None:
    grace = GoneGrace({"a", "b"}, grace_s=0.5)
    assert not grace.over({"b"}, now=0.0)
    assert not grace.over({"b"}, now=3.0)  # a's grace is long over, b is still there
    assert not grace.over(set(), now=3.1)
    assert grace.over(set(), now=3.61)
