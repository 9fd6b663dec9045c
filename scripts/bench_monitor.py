"""Benchmark what watching a run costs its control loop: 0, 1 and 10 `tidelink monitor --json`
processes attached to realtime launches (default: polling, plus the event streams; and 10
with --all, every message, for comparison), and one monitor that joined and was then
SIGSTOPped (at mission time STOP_AT_S, killed at the end).

Each case runs two launches (router, clock and four services as processes; the launcher is
this process, as `tidelink launch` is its own), each with its own fresh monitors:
1. the control-loop latency, measured as scripts/bench_runtime.py measures it: the runtime
   self-test loop, event-driven with a zero-delay network, whose plant reports each
   command's age on arrival (sensor sample -> command applied, three Zenoh hops through the
   router), at time scale 1. The AUV mission's services are periodic: a command's age at the
   vehicle there is mostly the modelled delay and the planner's period, not the transport;
2. the default mission (configs/default.toml, its lossy network) at --time-scale: its outcome,
   and the vehicle's reported command age (modelled delay + transport + hold until the next
   command) as a second, coarser look at the same loop.
Cases run interleaved, --rounds times, and each number is the median over the rounds. Ratios
are to 0 monitors (goal: <= 1.05 at p50). Every monitor shares this machine's cores with the
run, as a monitor on the vehicle's own computer would; the p50 of each round is printed too,
and the load average before each case: on a machine that others use, their spread says how
far a ratio can be trusted.

Then the recorder: the default mission recorded by a lockstep launch (--record) is replayed
faster and faster (`tidelink replay`, which serves watchers as a run's clock does) with a
remote `tidelink record` attached: frames offered per second (from the recorded log times),
recorded and lost, against the run's own rate.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from common.config.scenario import load_scenario
from common.messages import VehicleStatus
from common.runtime.metrics_record import RunMetrics
from common.runtime.processes.children import free_port
from common.world.check import check_scenario
from services.cli import build_parser
from services.launcher.launch import LaunchOptions, launch
from services.launcher.progress import MissionView

ROOT = Path(__file__).resolve().parents[1]
LOOP_TOML = """
[run]
name = "benchloop"
mission = "testloop"
max_time_s = {seconds}
[run.mission_params]
event_driven = true
[runtime]
kind = "realtime"
time_scale = 1.0
"""
STOP_AT_S = 2.0  # mission time at which the stopped case's monitor gets SIGSTOP
JOIN_S = 30.0


@dataclass(frozen=True)
class Case:
    name: str
    monitors: int
    stopped: bool = False
    args: tuple[str, ...] = ()  # more `tidelink monitor` arguments


CASES = (
    Case("0 monitors", 0),
    Case("1 monitor", 1),
    Case("10 monitors", 10),
    Case("10 with --all", 10, args=("--all",)),  # every message, for comparison
    Case("1 SIGSTOPped", 1, stopped=True),
)


class Monitors:
    """`tidelink monitor --json` processes on one router, their output in files."""

    def __init__(self, endpoint: str, n: int, folder: Path, args: tuple[str, ...]) -> None:
        self.endpoint = endpoint
        self.args = args
        self.files = [folder / f"monitor-{i}.jsonl" for i in range(n)]
        self.procs: list[subprocess.Popen[bytes]] = []
        self.cpu_s = 0.0
        self.codes: list[int | None] = []
        self.stopped: set[int] = set()

    def start(self) -> None:
        """Start them and wait until each is connected (it says it waits for a run)."""
        for path in self.files:
            with path.open("wb") as fh:
                self.procs.append(
                    subprocess.Popen(
                        [sys.executable, "-m", "services.cli", "monitor"]
                        + ["--connect", self.endpoint, "--json", *self.args],
                        cwd=ROOT,
                        stdin=subprocess.DEVNULL,
                        stdout=fh,
                        stderr=subprocess.STDOUT,
                        start_new_session=True,
                    )
                )
        deadline = time.monotonic() + JOIN_S
        for path, proc in zip(self.files, self.procs, strict=True):
            while b'"notice"' not in path.read_bytes() and b'"joined"' not in path.read_bytes():
                if proc.poll() is not None or time.monotonic() > deadline:
                    raise RuntimeError(f"monitor did not connect:\n{path.read_text()}")
                time.sleep(0.05)  # polling a file for a condition, with a deadline

    def stop_first(self) -> None:
        os.killpg(self.procs[0].pid, signal.SIGSTOP)
        self.stopped.add(self.procs[0].pid)

    def finish(self, timeout_s: float = 30.0) -> None:
        """Wait for them to leave by themselves (they exit when the run ends; a stopped one is
        killed, its exit code None). CPU time from each one's rusage."""
        deadline = time.monotonic() + timeout_s
        for proc in self.procs:
            code: int | None = None
            while proc.pid not in self.stopped and time.monotonic() < deadline:
                pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
                if pid:
                    code = os.waitstatus_to_exitcode(status)
                    self.cpu_s += usage.ru_utime + usage.ru_stime
                    break
                time.sleep(0.05)
            if code is None:
                os.killpg(proc.pid, signal.SIGKILL)
                _, status, usage = os.wait4(proc.pid, 0)
                self.cpu_s += usage.ru_utime + usage.ru_stime
            proc.returncode = code if code is not None else -9
            self.codes.append(code)

    def lines(self) -> list[list[dict[str, Any]]]:
        out = []
        for path in self.files:
            objs = []
            for line in path.read_text().splitlines():
                if line.startswith("{"):
                    objs.append(json.loads(line))
            out.append(objs)
        return out


class HookDisplay:
    """A launch display that prints nothing and calls hooks: when the router listens, and on
    each progress report with the mission time."""

    def __init__(self, on_router: Callable[[], None], on_progress: Callable[[float], None]) -> None:
        self.on_router = on_router
        self.on_progress = on_progress

    def update(self, view: MissionView, t_sim: float) -> None:
        self.on_progress(t_sim)

    def event(self, text: str) -> None:
        if text.startswith("router listening on"):
            self.on_router()

    def close(self) -> None:
        pass


@dataclass
class Run:
    """One launch with its monitors: command ages (s), metrics, what the monitors saw."""

    ages_s: list[float]
    metrics: RunMetrics[Any]
    monitor_cpu_s: float
    joined: int  # monitors that printed a joined event
    updates: list[int] = field(default_factory=list)  # update lines per monitor
    codes: list[int | None] = field(default_factory=list)


def run_case(scenario_path: Path, overrides: list[str], case: Case, status: str) -> Run:
    """One launch of a scenario with the case's monitors; `status` is the stream of
    VehicleStatus messages whose command ages are returned ("service/stream")."""
    s, raw = load_scenario(scenario_path, overrides, check=check_scenario)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    with tempfile.TemporaryDirectory(prefix="tidelink-bench-monitor-") as tmp:
        mons = Monitors(endpoint, case.monitors, Path(tmp), case.args)
        stopped = [False]

        def on_progress(t_sim: float) -> None:
            if case.stopped and not stopped[0] and t_sim >= STOP_AT_S:
                mons.stop_first()
                stopped[0] = True

        display = HookDisplay(mons.start, on_progress)
        opts = LaunchOptions(listen=(endpoint,), plot=False)
        try:
            outcome = launch(s, raw, Path(tmp) / "run", opts, display)
        finally:
            mons.finish()
        service, stream = status.split("/")
        ages = [
            m.command_age
            for m in outcome.result.record.stream(service, stream)
            if isinstance(m, VehicleStatus)
        ]
        seen = mons.lines()
    joined = sum(any(o.get("event") == "joined" for o in lines) for lines in seen)
    updates = [sum(o["type"] == "update" for o in lines) for lines in seen]
    if case.stopped and not stopped[0]:
        raise RuntimeError("the run ended before the monitor was stopped")
    return Run(ages, outcome.metrics, mons.cpu_s, joined, updates, mons.codes)


def loop_scenario(seconds: float, folder: Path) -> Path:
    """The self-test loop's scenario file for the latency runs, written in `folder`."""
    path = folder / "loop.toml"
    path.write_text(LOOP_TOML.format(seconds=seconds))
    return path


def pct(ages: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(ages), q))


def med(values: list[float]) -> float:
    return statistics.median(values)


def has_command(name: str) -> bool:
    """Whether `tidelink NAME` exists (as argparse's usage line lists the sub-commands)."""
    usage = build_parser().format_usage()
    return name in usage.split("{", 1)[-1].split("}", 1)[0].split(",")


def tidelink(*args: str, timeout_s: float = 300.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "services.cli", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=True,
    )


@dataclass
class Recorded:
    """One replay at `speed` recorded remotely: frames offered per second, recorded, lost."""

    speed: float
    offered_per_s: float
    recorded: int
    lost: int


def bench_recorder(speeds: tuple[float, ...]) -> tuple[int, float, list[Recorded]]:
    """The default mission recorded in a lockstep launch (--record), then replayed faster and
    faster (`tidelink replay`, which serves watchers as a run's clock does) with a remote
    `tidelink record` attached; returns (frames, the mission's seconds, one row per speed)."""
    from services.recording.reader import read_recording

    with tempfile.TemporaryDirectory(prefix="tidelink-bench-record-") as tmp:
        src = Path(tmp) / "src"
        launched = tidelink(
            "launch",
            str(ROOT / "configs" / "default.toml"),
            "--runtime",
            "lockstep",
            "--record",
            "--no-plot",
            "--json",
            "--out",
            str(src),
        )
        t_end = float(json.loads(launched.stdout)["t_end_s"])
        frames = len(read_recording(src / "run.mcap").frames)
        rows: list[Recorded] = []
        for speed in speeds:
            endpoint = f"tcp/127.0.0.1:{free_port()}"
            run = f"rec{len(rows)}"
            out = Path(tmp) / f"{run}.mcap"
            rec = subprocess.Popen(
                [sys.executable, "-m", "services.cli", "record", "--connect", endpoint]
                + ["--run", run, "-o", str(out)],
                cwd=ROOT,
                stdout=subprocess.PIPE,
                stderr=subprocess.DEVNULL,
                text=True,
            )
            # --lead 3: the recorder (polling for the router every 0.5 s) joins before frame 1
            tidelink(
                "replay",
                str(src / "run.mcap"),
                "--listen",
                endpoint,
                "--speed",
                f"{speed:g}",
                "--as",
                run,
                "--lead",
                "3",
            )
            stdout, _ = rec.communicate(timeout=120)
            got = read_recording(out).frames
            walls = [f.wall for f in got]
            span = max(walls) - min(walls) if walls else float("nan")
            m = re.search(r"lost (\d+) frames", stdout)
            rows.append(Recorded(speed, frames / span, len(got), int(m[1]) if m else 0))
    return frames, t_end, rows


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--rounds", type=int, default=2, help="interleaved repetitions (2)")
    p.add_argument("--loop-s", type=float, default=20.0, help="self-test loop seconds (20)")
    p.add_argument("--time-scale", type=float, default=4.0, help="default mission speed-up (4)")
    p.add_argument(
        "--replay-speeds",
        type=float,
        nargs="+",
        default=[1.0, 4.0, 16.0, 64.0, 128.0],
        help="recorder: replay speeds of the lockstep recording (1 4 16 64 128)",
    )
    p.add_argument("--only-recorder", action="store_true", help="skip the monitor cases")
    a = p.parse_args()
    if not a.only_recorder:
        bench_monitors(a)
    if not has_command("record"):
        print("recorder: `tidelink record` is not on this branch; not measured")
        return
    frames, t_end, rows = bench_recorder(tuple(a.replay_speeds))
    print(
        f"recorder (remote `tidelink record` of the default mission replayed faster and faster;"
        f" the run: {frames} frames in {t_end:.1f} s = {frames / t_end:.0f} frames/s at x1, "
        f"{a.time_scale * frames / t_end:.0f} at x{a.time_scale:g}):"
    )
    print("  replay speed  offered frames/s  x run's rate at x1  recorded  lost")
    for r in rows:
        print(
            f"  {r.speed:12g}  {r.offered_per_s:16.0f}  {r.offered_per_s * t_end / frames:18.1f}"
            f"  {r.recorded:8d}  {r.lost:4d}"
        )


def bench_monitors(a: argparse.Namespace) -> None:
    """Every case, interleaved over the rounds; prints the two tables."""
    from tests.helpers.testloop import register  # a fixture of tests/, not a built-in mission

    register(os.environ)  # for this process and the service processes it starts
    cases = CASES
    loop_toml = loop_scenario(a.loop_s, Path(tempfile.mkdtemp(prefix="tidelink-bench-")))
    default = ROOT / "configs" / "default.toml"
    mission_sets = ['runtime.kind="realtime"', f"runtime.time_scale={a.time_scale}"]
    loops: dict[str, list[Run]] = {c.name: [] for c in cases}
    missions: dict[str, list[Run]] = {c.name: [] for c in cases}
    load: dict[str, list[float]] = {c.name: [] for c in cases}
    for r in range(a.rounds):
        for c in cases:
            t0 = time.monotonic()
            load[c.name].append(os.getloadavg()[0])  # of the minute before: others' work too
            loops[c.name].append(run_case(loop_toml, [], c, "plant/status"))
            missions[c.name].append(run_case(default, mission_sets, c, "vehicle/status"))
            print(
                f"  round {r + 1}/{a.rounds} {c.name}: {time.monotonic() - t0:.0f} s "
                f"(load average before: {load[c.name][-1]:.2f})",
                file=sys.stderr,
                flush=True,
            )
    base50 = med([pct(x.ages_s, 50) for x in loops[CASES[0].name]])
    base95 = med([pct(x.ages_s, 95) for x in loops[CASES[0].name]])
    n = len(loops[CASES[0].name][0].ages_s)
    print(
        f"control loop (self-test loop, event-driven, zero-delay network, x1, {a.loop_s:g} s, "
        f"~{n} commands; median of {a.rounds} rounds): sensor sample -> command applied"
    )
    print(
        "  case            p50 us   p95 us   p50/0   p95/0   monitors joined  monitor CPU s"
        "  load before  p50 per round ms"
    )
    for c in cases:
        runs = loops[c.name]
        p50 = med([pct(x.ages_s, 50) for x in runs])
        p95 = med([pct(x.ages_s, 95) for x in runs])
        print(
            f"  {c.name:<14} {p50 * 1e6:7.0f}  {p95 * 1e6:7.0f}  {p50 / base50:6.3f}  "
            f"{p95 / base95:6.3f}   {min(x.joined for x in runs):2d} of {c.monitors:<2d}"
            f"         {med([x.monitor_cpu_s for x in runs]):6.1f}"
            f"  {med(load[c.name]):11.2f}  "
            + " ".join(f"{pct(x.ages_s, 50) * 1e3:.2f}" for x in runs)
        )
    print(
        f"default mission (configs/default.toml, lossy network, x{a.time_scale:g}): outcome per "
        "round; command age at the vehicle (modelled delay + transport + hold) p50 / p95"
    )
    print(
        "  case            end       goal  t_end s  travel s  min clear m  stale cmds  "
        "age p50 ms  age p95 ms  monitors joined"
    )
    for c in cases:
        for x in missions[c.name]:
            m = x.metrics.to_json()
            print(
                f"  {c.name:<14} {m['end_reason']:<9} {str(m.get('reached_goal')):<5} "
                f"{m['t_end_s']:7.2f}  {m.get('travel_time_s') or float('nan'):8.2f}  "
                f"{m.get('min_clearance_m', float('nan')):11.2f}  "
                f"{m.get('commands_rejected_stale', 0):10d}  {pct(x.ages_s, 50) * 1e3:10.1f}  "
                f"{pct(x.ages_s, 95) * 1e3:10.1f}  {x.joined:2d} of {c.monitors}"
            )


if __name__ == "__main__":
    main()
