"""What the launcher shows while a mission runs: a rich progress bar on a terminal, plain log
lines otherwise; plus notable events (exits, restarts, vehicle mode changes)."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import IO, Protocol

from common.config.scenario import Scenario
from common.messages import Message, PathMsg, TruthState, VehicleStatus
from common.runtime.model.silence import SilenceWatch

NO_PATH = "NO_PATH"  # PathMsg.status when the planner found no path
NO_PATH_ALARM_S = 5.0  # a NO_PATH lasting this long (mission s) is an alarm, not a hiccup
# the vehicle's true pose in any mission that has a vehicle (DESIGN.md: .../vehicle/truth);
# without it, progress is the mission time used
TRUTH = ("vehicle", "truth")


class MissionView:
    """The launcher's live picture of a run, built from the messages it records."""

    def __init__(self, scenario: Scenario) -> None:
        self.max_time_s = scenario.run.max_time_s
        self.goal = (scenario.world.goal.x_m, scenario.world.goal.y_m)
        self.t_sim = 0.0
        self.pose: tuple[float, float] | None = None
        self.d0: float | None = None  # distance to the goal at the first truth
        self.mode = ""
        self.path_status = ""
        self.no_path_since: float | None = None  # a NO_PATH that has not been lifted since
        self.no_path_reason = ""
        self.no_path_alarmed = False

    @property
    def to_goal_m(self) -> float | None:
        if self.pose is None:
            return None
        return math.hypot(self.pose[0] - self.goal[0], self.pose[1] - self.goal[1])

    def fraction(self) -> float:
        """Progress in [0, 1]: distance covered towards the goal, else time used."""
        d = self.to_goal_m
        if d is not None and self.d0:
            return min(1.0, max(0.0, 1.0 - d / self.d0))
        return min(1.0, self.t_sim / self.max_time_s)

    def see(self, service: str, stream: str, msg: Message) -> str | None:
        """Take one recorded message; returns a line worth reporting (a mode change), if any."""
        self.t_sim = max(self.t_sim, msg.stamp)
        if isinstance(msg, TruthState) and (service, stream) == TRUTH:
            self.pose = (msg.x, msg.y)
            if self.d0 is None:
                self.d0 = self.to_goal_m
        elif isinstance(msg, VehicleStatus) and msg.mode != self.mode:
            old, self.mode = self.mode, msg.mode
            if old:
                return f"{service}: mode {old} -> {msg.mode} at t={msg.stamp:.2f} s"
        elif isinstance(msg, PathMsg) and msg.status != self.path_status:
            old, self.path_status = self.path_status, msg.status
            if msg.status == NO_PATH:
                self.no_path_since, self.no_path_reason = msg.stamp, msg.reason
            else:
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
        d = self.to_goal_m
        parts = [f"t={t_sim:7.2f} s of {self.max_time_s:g}"]
        if d is not None:
            parts.append(f"to goal {d:6.1f} m")
        parts.append(f"{100 * self.fraction():3.0f}%")
        if self.mode:
            parts.append(f"mode {self.mode}")
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


def make_display(out: IO[str]) -> Display:
    """A progress bar if `out` is a terminal, else plain lines."""
    if out.isatty():
        return RichDisplay(out)
    return PlainDisplay(out)


class LoggedDisplay:
    """A display that also appends every event, time-stamped, to a log file (launch.log)."""

    def __init__(self, inner: Display, path: Path) -> None:
        self.inner = inner
        path.parent.mkdir(parents=True, exist_ok=True)
        self._fh = path.open("w")

    def update(self, view: MissionView, t_sim: float) -> None:
        self.inner.update(view, t_sim)

    def event(self, text: str) -> None:
        self._fh.write(f"{time.strftime('%H:%M:%S')} {text}\n")
        self._fh.flush()
        self.inner.event(text)

    def close(self) -> None:
        self._fh.close()
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
