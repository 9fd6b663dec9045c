"""A realtime loop's timed waits end on time: the thread's timer slack cut to 1 us (Linux).

Linux lets a sleeping thread's timer fire up to its timer slack late (50 us by default), to
batch wake-ups. A realtime service sleeps until its next step in a timed wait, so every
periodic step started that much later than due (docs/notes/0032-realtime-timer-slack.md).
"""

from __future__ import annotations

import ctypes
import logging
import sys

PR_SET_TIMERSLACK = 29  # <linux/prctl.h>
REALTIME_SLACK_NS = 1000

log = logging.getLogger("tidelink.realtime")


def tighten_timer_slack(slack_ns: int = REALTIME_SLACK_NS) -> bool:
    """Set the calling thread's timer slack (threads it starts later inherit it); False where
    the OS has no such setting or refuses it, which costs only the precision above."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        ok = libc.prctl(PR_SET_TIMERSLACK, ctypes.c_ulong(slack_ns), 0, 0, 0) == 0
    except (OSError, AttributeError):
        ok = False
    if not ok:
        log.debug("timer slack left as it was (prctl refused)")
    return ok
