"""The path in force sent again while the controller is onboard (services/planner/repeat.py)."""

from __future__ import annotations

import msgspec
from helpers.samples import one_of_each

from common.messages import PathMsg
from services.mission.metrics import distinct_paths
from services.planner.repeat import PathRepeat


def _path(path_id: int, stamp: float) -> PathMsg:
    sample = next(m for m in one_of_each() if isinstance(m, PathMsg))
    return msgspec.structs.replace(sample, path_id=path_id, stamp=stamp)


def test_the_path_in_force_is_due_again_every_period_restamped() -> None:
    r = PathRepeat(2.0)
    assert r.due(5.0) is None  # nothing sent yet
    r.sent(1.0, _path(3, 1.0))
    assert r.due(2.9) is None
    again = r.due(3.0)
    assert again is not None and again.path_id == 3 and again.stamp == 3.0
    assert r.due(4.9) is None and r.due(5.0) is not None
    r.sent(5.5, _path(4, 5.5))  # a newer path restarts the count
    assert r.due(7.0) is None and r.due(7.5) == _path(4, 7.5)


def test_never_when_off() -> None:
    r = PathRepeat(0.0)
    r.sent(0.0, _path(1, 0.0))
    assert r.due(100.0) is None


def test_readers_count_a_path_once_as_first_sent() -> None:
    paths = [_path(1, 0.0), _path(1, 2.0), _path(2, 3.0), _path(1, 4.0), _path(2, 5.0)]
    assert [(p.path_id, p.stamp) for p in distinct_paths(paths)] == [(1, 0.0), (2, 3.0)]


def test_a_new_path_goes_out_at_once_and_restarts_the_count() -> None:
    r = PathRepeat(2.0)
    assert r.outgoing(1.0, None) is None
    assert r.outgoing(1.0, _path(1, 1.0)) == _path(1, 1.0)
    assert r.outgoing(2.0, None) is None and r.outgoing(3.0, None) == _path(1, 3.0)
