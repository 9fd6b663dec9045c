"""What the launcher shows while a mission runs: a rich progress bar on a terminal, plain log
lines otherwise; plus notable events (exits, restarts, vehicle mode changes)."""

from __future__ import annotations

import contextlib
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Protocol, TextIO

from common.config.scenario import Scenario
from common.messages import Message, PathMsg, TruthState, VehicleStatus
from common.runtime.model.dataflow import qualified, vehicle_of
from common.runtime.model.silence import SilenceWatch

NO_PATH = "NO_PATH"  # PathMsg.status when the planner found no path
NO_PATH_ALARM_S = 5.0  # a NO_PATH lasting this long (mission s) is an alarm, not a hiccup
# the vehicle's true pose in any mission that has a vehicle (DESIGN.md: .../vehicle/truth; a
# fleet's "<id>.vehicle"); without it, progress is the mission time used
TRUTH = ("vehicle", "truth")


@dataclass
class VehicleProgress:
    """One vehicle's way to its goal, as the launcher sees it."""

    goal: tuple[float, float]
    pose: tuple[float, float] | None = None
    d0: float | None = None  # distance to the goal at the first truth
    mode: str = ""

    @property
    def to_goal_m(self) -> float | None:
        if self.pose is None:
            return None
        return math.hypot(self.pose[0] - self.goal[0], self.pose[1] - self.goal[1])

    def fraction(self) -> float | None:
        d = self.to_goal_m
        if d is None or not self.d0:
            return None
        return min(1.0, max(0.0, 1.0 - d / self.d0))


class MissionView:
    """The launcher's live picture of a run (every vehicle of a fleet), from what it records."""

    def __init__(self, scenario: Scenario) -> None:
        self.max_time_s = scenario.run.max_time_s
        members = scenario.members or (("", scenario),)
        # by the name of each vehicle service: "vehicle", or a fleet's "auv2.vehicle"
        self.vehicles = {
            (qualified(vid, TRUTH[0]) if vid else TRUTH[0]): VehicleProgress(
                goal=(m.world.goal.x_m, m.world.goal.y_m)
            )
            for vid, m in members
        }
        self.t_sim = 0.0
        self.path_status: dict[str, str] = {}  # by planner
        self.no_path_since: float | None = None  # a NO_PATH that has not been lifted since
        self.no_path_reason = ""
        self.no_path_alarmed = False

    @property
    def to_goal_m(self) -> float | None:
        """The distance left to the goal (of the vehicle furthest from its own)."""
        left = [d for v in self.vehicles.values() if (d := v.to_goal_m) is not None]
        return max(left) if left else None

    def fraction(self) -> float:
        """Progress in [0, 1]: distance covered towards the goal (the mean over a fleet's
        vehicles), else time used."""
        done = [f for v in self.vehicles.values() if (f := v.fraction()) is not None]
        if done:
            return sum(done) / len(self.vehicles)
        return min(1.0, self.t_sim / self.max_time_s)

    def see(self, service: str, stream: str, msg: Message) -> str | None:
        """Take one recorded message; returns a line worth reporting (a mode change), if any."""
        self.t_sim = max(self.t_sim, msg.stamp)
        vehicle = self.vehicles.get(service)
        if isinstance(msg, TruthState) and vehicle is not None and stream == TRUTH[1]:
            vehicle.pose = (msg.x, msg.y)
            if vehicle.d0 is None:
                vehicle.d0 = vehicle.to_goal_m
        elif isinstance(msg, VehicleStatus) and vehicle is not None and msg.mode != vehicle.mode:
            old, vehicle.mode = vehicle.mode, msg.mode
            if old:
                return f"{service}: mode {old} -> {msg.mode} at t={msg.stamp:.2f} s"
        elif isinstance(msg, PathMsg) and msg.status != self.path_status.get(service, ""):
            old = self.path_status.get(service, "")
            self.path_status[service] = msg.status
            if msg.status == NO_PATH:
                self.no_path_since, self.no_path_reason = msg.stamp, f"{service}: {msg.reason}"
            elif NO_PATH not in self.path_status.values():
                self.no_path_since, self.no_path_alarmed = None, False
            if old:
                return (
                    f"{service}: path {old} -> {msg.status} at t={msg.stamp:.2f} s ({msg.reason})"
                )
        return None

    def alarm(self, t_sim: float) -> str | None:
        """A line once a NO_PATH has lasted NO_PATH_ALARM_S (the vehicle is not moving on)."""
        since = self.no_path_since
        if since is None or self.no_path_alarmed or t_sim - since < NO_PATH_ALARM_S:
            return None
        self.no_path_alarmed = True
        return (
            f"ALARM: planner NO_PATH since t={since:.2f} s ({t_sim - since:.1f} s; "
            f"{self.no_path_reason})"
        )

    def summary(self, t_sim: float) -> str:
        parts = [f"t={t_sim:7.2f} s of {self.max_time_s:g}"]
        if len(self.vehicles) == 1:
            (v,) = self.vehicles.values()
            if (d := v.to_goal_m) is not None:
                parts.append(f"to goal {d:6.1f} m")
            parts.append(f"{100 * self.fraction():3.0f}%")
            if v.mode:
                parts.append(f"mode {v.mode}")
            return "  ".join(parts)
        parts.append(f"{100 * self.fraction():3.0f}%")
        for name, v in self.vehicles.items():  # a fleet: every vehicle, distance and mode
            d = v.to_goal_m
            left = "?" if d is None else f"{d:.0f} m"
            parts.append(f"{vehicle_of(name)} {left} {v.mode}".rstrip())
        return "  ".join(parts)


class Display(Protocol):
    """Where progress and events go."""

    def update(self, view: MissionView, t_sim: float) -> None: ...

    def event(self, text: str) -> None: ...

    def close(self) -> None: ...


class PlainDisplay:
    """Log lines (for pipes, files and CI): events at once, progress every `every_s` seconds."""

    def __init__(self, out: IO[str], every_s: float = 2.0) -> None:
        self.out = out
        self.every_s = every_s
        self._next = 0.0

    def update(self, view: MissionView, t_sim: float) -> None:
        now = time.monotonic()
        if now >= self._next:
            self._next = now + self.every_s
            self._line(view.summary(t_sim))

    def event(self, text: str) -> None:
        self._line(text)

    def _line(self, text: str) -> None:
        stamp = time.strftime("%H:%M:%S")
        print(f"{stamp} launch: {text}", file=self.out, flush=True)

    def close(self) -> None:
        self.out.flush()


class RichDisplay:
    """A live progress bar (rich) on a terminal; events are printed above it."""

    def __init__(self, out: IO[str]) -> None:
        from rich.console import Console
        from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

        self.progress = Progress(
            TextColumn("[bold]mission"),
            BarColumn(),
            TextColumn("{task.fields[info]}"),
            TimeElapsedColumn(),
            console=Console(file=out),
            transient=False,
        )
        self.task = self.progress.add_task("mission", total=1000, info="starting")
        self.progress.start()

    def update(self, view: MissionView, t_sim: float) -> None:
        self.progress.update(
            self.task, completed=round(1000 * view.fraction()), info=view.summary(t_sim)
        )

    def event(self, text: str) -> None:
        self.progress.console.print(text, markup=False, highlight=False)

    def close(self) -> None:
        self.progress.stop()


def make_display(out: IO[str], *, every_s: float = 2.0) -> Display:
    """A progress bar if `out` is a terminal, else plain lines, one every `every_s` seconds."""
    if out.isatty():
        return RichDisplay(out)
    return PlainDisplay(out, every_s)


class LoggedDisplay:
    """A display that also appends every event, time-stamped, to a log file (launch.log)."""

    def __init__(self, inner: Display, path: Path) -> None:
        self.inner = inner
        self.path = path
        path.parent.mkdir(parents=True, exist_ok=True)
        self._fh: TextIO | None = path.open("w")

    def update(self, view: MissionView, t_sim: float) -> None:
        self.inner.update(view, t_sim)

    def event(self, text: str) -> None:
        if self._fh is not None:
            try:
                self._fh.write(f"{time.strftime('%H:%M:%S')} {text}\n")
                self._fh.flush()
            except OSError as exc:  # a full disk ends the log, not the run
                self._drop(exc)
        self.inner.event(text)

    def _drop(self, exc: OSError) -> None:
        fh, self._fh = self._fh, None
        with contextlib.suppress(OSError):
            if fh is not None:
                fh.close()
        self.inner.event(f"{self.path}: could not write it ({exc}); the log goes on here only")

    def close(self) -> None:
        if self._fh is not None:
            try:
                self._fh.close()
            except OSError as exc:
                self._drop(exc)
        self.inner.close()


class ProgressObserver:
    """The launcher's RunObserver: messages feed the MissionView, which with events and the
    mission time drives the display; a service that falls silent raises an alarm."""

    def __init__(
        self, view: MissionView, display: Display, silence_limits: dict[str, float] | None = None
    ) -> None:
        self.view = view
        self.display = display
        self.silence = SilenceWatch(silence_limits or {})

    def event(self, text: str) -> None:
        self.display.event(text)

    def message(self, service: str, stream: str, msg: Message) -> None:
        for line in (self.view.see(service, stream, msg), self.silence.heard(service, msg)):
            if line:
                self.display.event(line)

    def progress(self, t_s: float) -> None:
        for line in [*self.silence.check(t_s), self.view.alarm(t_s)]:
            if line:
                self.display.event(line)
        self.display.update(self.view, t_s)
