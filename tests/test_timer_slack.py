"""The realtime services' timer slack: set on Linux (read back from the kernel), a no-op
that says so elsewhere."""

from __future__ import annotations

import ctypes
import sys
import threading

from common.runtime.processes.timer_slack import REALTIME_SLACK_NS, tighten_timer_slack

PR_GET_TIMERSLACK = 30  # <linux/prctl.h>: the calling thread's slack, as the return value
LINUX = sys.platform.startswith("linux")


def _slack_ns() -> int:
    return int(ctypes.CDLL(None).prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0)) if LINUX else -1


def test_the_thread_that_tightens_its_slack_has_it_and_others_keep_theirs() -> None:
    seen: dict[str, int | bool] = {}

    def tighten() -> None:
        seen["before"] = _slack_ns()
        seen["ok"] = tighten_timer_slack()
        seen["after"] = _slack_ns()

    t = threading.Thread(target=tighten)
    t.start()
    t.join()
    assert seen["ok"] is LINUX  # elsewhere there is no such setting: False, nothing raised
    if LINUX:
        assert seen["after"] == REALTIME_SLACK_NS
        assert seen["before"] != REALTIME_SLACK_NS  # the default (50 us): the call changed it
        assert _slack_ns() != REALTIME_SLACK_NS  # this thread's is its own
