"""Replaying a recording (`tidelink replay`): its frames back on the bus, as a live run.

The frames go out with their original attachments and timing (log times, scaled by
`speed`) to what watchers read, and only there: a bus that serves watchers what a run's clock
serves them (common/runtime/distributed/bringup.py serve_watchers: the dataflow, the
scenario, the newest frames and the watch copies) is fed the recorded frames; nothing goes
on a run's control keys, so no service can take a replayed frame for a live one. The
recorded services' liveliness tokens and the clock's are declared while it plays; it ends
with the recorded RunEnd. Monitors and Foxglove bridges cannot tell it from a live run
(except by its run name, with `as_run`).

A replay holds its run's clock role (common/runtime/distributed/claim.py): it never plays
into a run that is live on the router (`claim_run` refuses), and no launch of that run can
start on the router while it plays.
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass

from common.bus import CLOCK, Bus, Keys
from common.bus.keys import END
from common.bus.probe import puts_reach_router
from common.config.scenario import scenario_from_raw
from common.jsonsafe import JsonObject
from common.runtime.distributed.bringup import serve_watchers
from common.runtime.distributed.claim import RoleTaken, claim
from common.runtime.model.mission import load_mission
from common.runtime.processes.signals import StopRequest
from services.recording.reader import AliveEvent, Recording, RecordingError

STEP_S = 0.1  # longest wait between looks at the stop request


@dataclass(frozen=True)
class ReplayOutcome:
    """How a replay went: frames published, and the end it announced."""

    keys: Keys
    published: int
    reason: str


def replay_scenario(rec: Recording, run: str) -> JsonObject:
    """The recorded scenario, named `run` (a replay under another name answers as that run)."""
    raw = copy.deepcopy(rec.scenario_raw)
    table = raw.setdefault("run", {})
    if not isinstance(table, dict):  # a recorded scenario was validated when it ran
        raise RecordingError(f"{rec.path}: its scenario's run is not a table")
    table["name"] = run
    return raw


def services_of(rec: Recording) -> list[str]:
    """The services whose tokens the replay declares: those seen alive in the recording, or
    (a recording without liveliness) those that published."""
    alive = {e.service for e in rec.events if isinstance(e, AliveEvent) and e.alive}
    if not alive:
        alive = {f.service for f in rec.frames}
    return sorted(alive - {CLOCK})


def replay(
    rec: Recording,
    bus: Bus,
    *,
    speed: float,
    stop: StopRequest,
    lead_s: float = 1.0,
    say: Callable[[str], None] = lambda text: None,
) -> ReplayOutcome:
    """Publish `rec` on `bus` (opened with the replay's Keys); see the module docstring.

    `lead_s`: after the tokens are declared, before the first frame, as a run's services
    take a moment to come up: watchers that join with the run see it from its start.
    """
    if speed <= 0:
        raise ValueError(f"--speed: {speed:g} must be > 0")
    keys = bus.keys
    raw = replay_scenario(rec, keys.run)
    flow = load_mission(scenario_from_raw(raw, f"{rec.path} (its scenario)")).dataflow
    tap = serve_watchers(bus, keys, flow, raw, listen=False)
    for service in services_of(rec):
        bus.declare_alive(service)
    bus.declare_alive(CLOCK)
    frames = [f for f in rec.frames if (f.service, f.stream) != (CLOCK, END)]
    t0 = min((f.wall for f in rec.frames), default=0.0)
    start = time.monotonic() + lead_s
    say(f"replaying {len(frames)} frames of {rec.run}/{rec.vehicle} as {keys.run} (x{speed:g})")
    sent = 0
    for f in frames:
        if not _wait_until(start + (f.wall - t0) / speed, stop):
            break
        tap.feed(f.service, f.stream, f.payload, f.attachment)  # the watch copy only
        sent += 1
    end = rec.end
    if stop.requested:
        reason, t_end, ticks = "interrupted", 0.0, 0
    elif end is None:
        reason, t_end, ticks = "recording-cut-short", 0.0, 0
    else:
        reason, t_end, ticks = end.reason, end.stamp, end.ticks
        ends = [f.wall for f in rec.frames if (f.service, f.stream) == (CLOCK, END)]
        _wait_until(start + (ends[-1] - t0) / speed, stop)
    tap.end(reason, t_end, ticks)
    return ReplayOutcome(keys, sent, reason)


def claim_run(bus: Bus) -> None:
    """Take the clock's role of the run `bus` replays as; RoleTaken when the run is live on
    the router (its clock holds the role, or any of its services' tokens is there), or
    another replay of it plays. PermissionError when the router drops this replay's puts (its
    access control denies them: nothing would reach a watcher)."""
    keys = bus.keys
    alive = bus.alive_now(keys.all_alive, timeout_s=1.0)
    if alive:
        who = ", ".join(sorted(Keys.parse_alive(k)[2] for k in alive))
        raise RoleTaken(f"run {keys.run}/{keys.vehicle} is live on the router ({who})")
    claim(bus, keys, CLOCK, wait_s=0.0)
    if not puts_reach_router(bus, keys.probe):
        raise PermissionError(
            f"the router drops what this replay puts on {keys.all_watch} (its access control "
            f"denies identity {bus.identity or '(none)'!r} there): no watcher would see it"
        )


def _wait_until(t: float, stop: StopRequest) -> bool:
    """Sleep until monotonic time `t` (the replay's pacing); False if asked to stop."""
    while not stop.requested:
        left = t - time.monotonic()
        if left <= 0:
            return True
        time.sleep(min(left, STEP_S))
    return False
