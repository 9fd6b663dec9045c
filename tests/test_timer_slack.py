"""The realtime services' timer slack: set on Linux, read back from the kernel."""

from __future__ import annotations

import ctypes
import sys
import threading

import pytest

from common.runtime.processes.timer_slack import REALTIME_SLACK_NS, tighten_timer_slack

PR_GET_TIMERSLACK = 30  # <linux/prctl.h>: the calling thread's slack, as the return value


def _slack_ns() -> int:
    return int(ctypes.CDLL(None).prctl(PR_GET_TIMERSLACK, 0, 0, 0, 0))


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="timer slack is Linux's")
def test_the_thread_that_tightens_its_slack_has_it_and_others_keep_theirs() -> None:
    seen: dict[str, int | bool] = {}

    def tighten() -> None:
        seen["before"] = _slack_ns()
        seen["ok"] = tighten_timer_slack()
        seen["after"] = _slack_ns()

    t = threading.Thread(target=tighten)
    t.start()
    t.join()
    assert seen["ok"] is True
    assert seen["after"] == REALTIME_SLACK_NS
    assert seen["before"] != REALTIME_SLACK_NS  # the default (50 us): the call changed it
    assert _slack_ns() != REALTIME_SLACK_NS  # this thread's is its own
