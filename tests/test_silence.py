"""Silence detection: gaps in what a periodic service publishes (common/runtime/model/silence)."""

from __future__ import annotations

from common.messages import LinkStats
from common.runtime.model.record import Record
from common.runtime.model.silence import SilenceWatch, unresponsive_s


def stats(t: float, seq: int) -> LinkStats:
    return LinkStats(stamp=t, source="planner", seq=seq, sent=t, links=[])


def test_only_the_time_overdue_beyond_the_limit_counts() -> None:
    record = Record()
    times = [1.0, 2.0, 3.0, 11.0, 12.0]  # 8 s of silence between 3 and 11
    for i, t in enumerate(times, 1):
        record.add("planner", "stats", stats(t, i))
    got = unresponsive_s(record, {"planner": 3.0, "sensor": 3.0}, t_end=12.5)
    assert got["planner"] == 5.0  # 8 s gap - 3 s limit
    assert got["sensor"] == 12.5 - 3.0  # never spoke: silent from the start to the end


def test_the_watch_says_once_when_silent_and_once_when_back() -> None:
    watch = SilenceWatch({"planner": 3.0})
    assert watch.heard("planner", stats(1.0, 1)) is None
    assert watch.check(3.9) == []
    lines = watch.check(4.1)
    assert len(lines) == 1 and "planner unresponsive since t=1.00 s" in lines[0]
    assert watch.check(6.0) == []  # said once
    back = watch.heard("planner", stats(9.0, 2))
    assert back is not None and "silent 8.0 s" in back
    assert watch.heard("estimator", stats(9.0, 1)) is None  # not judged


def test_a_lasting_no_path_raises_one_alarm_and_a_path_clears_it() -> None:
    from helpers.samples import one_of_each

    from common.config.scenario import Scenario
    from common.messages import PathMsg, replace
    from services.launcher.progress import NO_PATH_ALARM_S, MissionView

    ok = next(m for m in one_of_each() if isinstance(m, PathMsg) and m.status == "OK")
    no = replace(ok, status="NO_PATH", reason="start in contact")
    view = MissionView(Scenario())
    view.see("planner", "path", replace(ok, stamp=1.0))
    view.see("planner", "path", replace(no, stamp=2.0))
    assert view.alarm(2.0 + NO_PATH_ALARM_S - 0.1) is None
    line = view.alarm(2.0 + NO_PATH_ALARM_S + 0.1)
    assert line is not None and "NO_PATH since t=2.00 s" in line and "start in contact" in line
    assert view.alarm(30.0) is None  # once
    view.see("planner", "path", replace(ok, stamp=31.0))
    assert view.no_path_since is None and view.alarm(40.0) is None
