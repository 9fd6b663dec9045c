"""Faults from outside the loop (issue 61): what the tools around a run could do to it.

- watchers: a `tidelink monitor --json` and a `tidelink record`, SIGSTOPped together for
  hold_s wall seconds (the router closes their sessions after their lease);
- duplicate: a second `tidelink service NAME` joining the running mission; it needs the run
  to last ~5 wall seconds past the strike (its Python start, then claim.CLAIM_WAIT_S for the
  holder to go): sooner, the run ends meanwhile, the holder's claim goes with it and the
  duplicate takes the role as a restart would (short.toml at 6x: not refused, exit 0; at 1x
  refused);
- replay: the run recorded from its start by `tidelink record`, stopped, and replayed with
  `tidelink replay --connect` into the run's own router, under the run's own name;
- forge_tick: one Tick put on the tick key of every service, hold_s mission seconds ahead.

Each starts what it needs with the launch (`OutsideFault.start`), strikes at the fault's time
and, once the launch is over, reports what its processes did (`finish`), for the verdict.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

from common.bus import Bus, Keys
from common.bus.probe import puts_reach_router
from common.bus.watcher import Watcher
from common.config.bus import client_config
from common.messages import Tick, WireError, decode, encode
from common.runtime.model.dataflow import Dataflow

EXIT_WAIT_S = 60.0  # how long a helper process may take to end once the launch has
LOOP_STREAM = ("vehicle", "truth")  # the loop's pulse: its gaps are the loop's period held


@dataclass(frozen=True)
class HelperResult:
    """How a helper process ended: its exit code (None: it hung, and was killed) and the
    last 2000 characters of its stdout and stderr."""

    exit: int | None
    stdout: str
    stderr: str


@dataclass
class OutsideReport:
    """What a fault from outside the loop came to: each helper's result by name, and (the
    watchers) the longest gap of the loop in the launch's own recording."""

    helpers: dict[str, HelperResult] = field(default_factory=dict)
    loop_gap_s: float | None = None

    def to_json(self) -> dict[str, object]:
        """As chaos.json has it: each helper's result under its name, and loop_gap_s."""
        flat: dict[str, object] = {name: asdict(r) for name, r in self.helpers.items()}
        return flat if self.loop_gap_s is None else flat | {"loop_gap_s": self.loop_gap_s}


@dataclass
class Helper:
    """A CLI process of the case, its output in files (no pipe can fill and stop it)."""

    name: str
    proc: subprocess.Popen[bytes]
    out: Path
    err: Path

    def result(self) -> HelperResult:
        """How it ended, given EXIT_WAIT_S to end by itself (then killed: it hung)."""
        try:
            code: int | None = self.proc.wait(EXIT_WAIT_S)
        except subprocess.TimeoutExpired:
            code = None  # it hung
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait()
        return HelperResult(
            exit=code,
            stdout=self.out.read_text(errors="replace")[-2000:],
            stderr=self.err.read_text(errors="replace")[-2000:],
        )


@dataclass
class OutsideFault:
    """The helper processes of one case and what came of them."""

    kind: str
    target: str
    hold_s: float
    out: Path
    endpoint: str
    scenario: Path
    sets: tuple[str, ...]
    time_scale: float
    helpers: dict[str, Helper] = field(default_factory=dict)
    report: OutsideReport = field(default_factory=OutsideReport)

    def _cli(self, name: str, *args: str) -> Helper:
        """Helper `name`: `tidelink ARGS --connect ENDPOINT` (every helper joins the run's
        router), its output in out/NAME.out and .err."""
        self.out.mkdir(parents=True, exist_ok=True)
        out, err = self.out / f"{name}.out", self.out / f"{name}.err"
        with out.open("wb") as o, err.open("wb") as e:
            proc = subprocess.Popen(
                [sys.executable, "-m", "services.cli", *args, "--connect", self.endpoint],
                stdout=o,
                stderr=e,
                stdin=subprocess.DEVNULL,
                start_new_session=True,
                env=dict(os.environ, PYTHONUNBUFFERED="1"),
            )
        self.helpers[name] = Helper(name, proc, out, err)
        return self.helpers[name]

    def _run_to_end(self, name: str, *args: str) -> None:
        """Helper `name` (as _cli), waited for: how it ended goes into the report."""
        self.report.helpers[name] = self._cli(name, *args).result()

    def launch_args(self) -> list[str]:
        """What the launch adds for this fault (watchers: its own lossless recording, whose
        timing says whether the loop kept its period)."""
        return ["--record"] if self.kind == "watchers" else []

    def start(self) -> None:
        """The helpers that must be there from the run's start."""
        if self.kind == "watchers":
            self._cli("monitor", "monitor", "--json")
            self._cli("record", "record", "-o", str(self.out / "watched.mcap"))
        elif self.kind == "replay":
            self._cli("record", "record", "-o", str(self.out / "recorded.mcap"))

    def strike(self, keys: Keys, flow: Dataflow) -> int:
        """Apply the fault; returns the frames put (a forged Tick: 1)."""
        if self.kind == "watchers":
            watchers = [self.helpers["monitor"].proc, self.helpers["record"].proc]
            for p in watchers:
                os.killpg(p.pid, signal.SIGSTOP)
            try:
                time.sleep(self.hold_s)  # the stop's length, in wall seconds, is the fault
            finally:
                for p in watchers:
                    os.killpg(p.pid, signal.SIGCONT)
            return 0
        if self.kind == "duplicate":
            scale = ("--time-scale", f"{self.time_scale:g}")
            sets = [x for s in self.sets for x in ("--set", s)]
            # refused within seconds, or it hangs on
            self._run_to_end("duplicate", "service", self.target, str(self.scenario), *scale, *sets)
            return 0
        if self.kind == "replay":
            rec = self.helpers["record"]
            os.killpg(rec.proc.pid, signal.SIGTERM)  # its file is closed: a recording so far
            self.report.helpers["record"] = rec.result()
            speed = ("--speed", f"{self.time_scale:g}")
            self._run_to_end("replay", "replay", str(self.out / "recorded.mcap"), *speed)
            return 0
        if self.kind == "forge_tick":
            return forge_tick(self.endpoint, keys, flow, ahead_s=self.hold_s)
        raise ValueError(f"not a fault from outside the loop: {self.kind!r}")

    def finish(self) -> OutsideReport:
        """What every helper did (each given EXIT_WAIT_S to end by itself)."""
        for name, h in self.helpers.items():
            if name not in self.report.helpers:
                self.report.helpers[name] = h.result()
        if self.kind == "watchers":
            self.report.loop_gap_s = loop_gap_s(self.out / "run.mcap", self.time_scale)
        return self.report


def forge_tick(connect: str, keys: Keys, flow: Dataflow, *, ahead_s: float) -> int:
    """Put one Tick for every service of the run, `ahead_s` mission seconds ahead of the
    newest frame the run's tap has: a plain client of the router, as anyone could."""
    with Bus(client_config(connect, None), keys, identity="monitor") as bus:
        now = 0.0
        for f in Watcher(bus, keys.run, keys.vehicle).latest(keys):
            try:
                now = max(now, decode(f.payload).stamp)
            except WireError:
                continue
        t = now + ahead_s
        tick = Tick(stamp=t, tick=10**6, time_us=round(t * 1e6))
        pub = bus.publisher_on(keys.tick(flow.names))
        pub.put_bytes(encode(tick))  # as the run's clock puts its Ticks
        # closed at once, the session could drop the put: a probe's round trip through the
        # router, sent after it on the same link, says it went (else: none was forged)
        return 1 if puts_reach_router(bus, keys.probe) else 0


def loop_gap_s(mcap: Path, time_scale: float) -> float | None:
    """The longest gap (mission seconds) between two of the loop's frames (LOOP_STREAM) as the
    run's tap got them, in the launch's own recording; None without one."""
    from services.recording.reader import read_recording

    try:
        rec = read_recording(mcap)
    except Exception:  # noqa: BLE001 - no recording: no measure, said as None
        return None
    walls = sorted(f.wall for f in rec.frames if (f.service, f.stream) == LOOP_STREAM)
    gaps = [b - a for a, b in zip(walls, walls[1:], strict=False)]
    return max(gaps, default=0.0) * time_scale
