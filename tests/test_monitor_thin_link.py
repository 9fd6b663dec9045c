"""`tidelink monitor --rate` over a 64 kbit/s link keeps the vehicle's state under 1 s old.

The run (router, clock, services) is one "host" (network namespace); two monitors sit on two
others, each behind its own veth link shaped both ways with `tc ... tbf rate 64kbit burst
4kb latency 400ms`. One polls the run's latest state (`--rate 2`); the other takes the full
stream of tapped frames, which does not fit such a link: its numbers are printed (run with
-s) as the evidence for --rate, never asserted. Ages are wall seconds between the run's tap
getting a frame and the monitor's update line showing it (one machine: one clock).
"""

from __future__ import annotations

import json
import signal
import subprocess
import time
from collections.abc import Iterator
from contextlib import ExitStack
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from helpers.launch_proc import REPO, Tidelink, kill_recorded
from helpers.netns import Tbf, Veth, lab_or_skip, link_bytes, shape, tbf

pytestmark = [pytest.mark.slow, pytest.mark.netns, pytest.mark.exclusive]

PORT = 7447
WAIT_S = 60.0
RUN_S = 6.0  # mission seconds at time scale 1: ~12 monitor updates
SHAPER = ("64kbit", "4kb", "400ms")  # rate, burst, latency
RATE_KBIT = 64.0
TRUTH = "vehicle/truth"
TRUTH_PERIOD_S = 0.05  # configs/default.toml: vehicle.period_s
MAX_AGE_S = 1.0


@dataclass
class ThinHosts:
    """The run's namespace and two monitor namespaces behind shaped links."""

    run: str
    polled: Veth  # for the --rate monitor
    full: Veth  # for the full-stream monitor
    shapers: dict[str, Tbf]


@pytest.fixture
def thin() -> Iterator[ThinHosts]:
    with lab_or_skip(need_tc=True) as lab:
        run = lab.namespace("r")
        polled = lab.veth(run, lab.namespace("m1"), "10.202.1", "p")
        full = lab.veth(run, lab.namespace("m2"), "10.202.2", "f")
        shapers = {}
        for v in (polled, full):  # both directions of both links
            shapers[v.dev_a] = shape(v.ns_a, v.dev_a, *SHAPER)
            shapers[v.dev_b] = shape(v.ns_b, v.dev_b, *SHAPER)
        yield ThinHosts(run, polled, full, shapers)


@dataclass
class Seen:
    """What a monitor's JSON lines say about the vehicle's true state."""

    joined: bool
    ages: list[float]  # of the newest truth at each update while newer truth kept coming
    updates: list[dict[str, Any]]
    last_stamp: float  # mission time of the newest truth it showed
    count: int  # truth frames it took in all


def seen(lines: list[str]) -> Seen:
    objs = [json.loads(line) for line in lines if line.startswith("{")]
    joined = any(o["type"] == "event" and o.get("event") == "joined" for o in objs)
    updates = [o for o in objs if o["type"] == "update" and TRUTH in o["streams"]]
    last = max((u["streams"][TRUTH]["stamp"] for u in updates), default=-1.0)
    # an update after the newest truth frame measures the run's end, not the link
    ages = [u["streams"][TRUTH]["age_s"] for u in updates if u["streams"][TRUTH]["stamp"] < last]
    count = max((u["streams"][TRUTH]["count"] for u in updates), default=0)
    return Seen(joined, ages, updates, last, count)


def pcts(ages: list[float]) -> str:
    if not ages:
        return "no ages"
    a = np.asarray(ages)
    return (
        f"age p50 {np.percentile(a, 50):.3f} s  p95 {np.percentile(a, 95):.3f} s  "
        f"max {a.max():.3f} s  ({len(a)} updates)"
    )


def stop(mon: Tidelink, timeout_s: float) -> int | None:
    """Its exit code, or None when it had to be stopped (SIGINT) after timeout_s."""
    try:
        return mon.wait(timeout_s)
    except subprocess.TimeoutExpired:
        mon.signal(signal.SIGINT)
        mon.wait(15.0)
        return None


def test_a_polling_monitor_shows_the_vehicle_within_1_s_over_64_kbit(
    thin: ThinHosts, tmp_path: Path
) -> None:
    out = tmp_path / "run"
    sets = ("--set", f"run.max_time_s={RUN_S}")
    connect = {v.dev_a: f"tcp/{v.ip_a}:{PORT}" for v in (thin.polled, thin.full)}
    try:
        with ExitStack() as stack:
            launcher = stack.enter_context(
                Tidelink(
                    "launch",
                    str(REPO / "configs" / "default.toml"),
                    "--listen",
                    f"tcp/0.0.0.0:{PORT}",
                    "--insecure",  # the namespaces are this test's own network
                    "--time-scale",
                    "1",
                    "--out",
                    str(out),
                    "--no-plot",
                    *sets,
                    netns=thin.run,
                )
            )
            launcher.wait_for(r"router listening on", WAIT_S)
            polled = stack.enter_context(
                Tidelink(
                    "monitor",
                    "--connect",
                    connect[thin.polled.dev_a],
                    "--json",
                    "--rate",
                    "2",
                    "--every",
                    "0.5",
                    netns=thin.polled.ns_b,
                )
            )
            full = stack.enter_context(
                Tidelink(
                    "monitor",
                    "--connect",
                    connect[thin.full.dev_a],
                    "--json",
                    "--every",
                    "0.5",
                    netns=thin.full.ns_b,
                )
            )
            # the traffic of the mission itself, between its start and its end
            launcher.wait_for(r"mission clock started", WAIT_S)
            t0, before = time.time(), {v.dev_a: _bytes(v) for v in (thin.polled, thin.full)}
            launcher.wait_for(r"mission ended at", RUN_S + WAIT_S)
            t1, after = time.time(), {v.dev_a: _bytes(v) for v in (thin.polled, thin.full)}
            # exit 3: a mission cut at max_time short of the goal is no success
            assert launcher.wait(WAIT_S) == 3, launcher.stderr
            polled_code = stop(polled, WAIT_S)
            full_code = stop(full, 3.0)  # its backlog is evidence, not asserted: cut it short
    finally:
        kill_recorded(out / "pids.json")

    t_end = json.loads((out / "metrics.json").read_text())["t_end_s"]
    p, f = seen(polled.out), seen(full.out)
    window_s = t1 - t0
    polls = sum(1 for u in p.updates if t0 <= u["wall"] <= t1)
    use = {
        name: LinkUse.of(v, before[v.dev_a], after[v.dev_a], window_s)
        for name, v in (("polled", thin.polled), ("full", thin.full))
    }
    shaped = ", ".join(f"{d} {s.rate}/{s.burst}/{s.latency}" for d, s in thin.shapers.items())
    report = [
        f"links shaped (tbf rate/burst/latency as tc reports them): {shaped}",
        f"mission {t_end:.2f} s, {window_s:.1f} s wall; "
        f"{round(t_end / TRUTH_PERIOD_S) + 1} truth frames published",
        f"--rate 2: {pcts(p.ages)}; truth frames shown {p.count}, newest t={p.last_stamp:.2f} s; "
        f"{polls} polls, {use['polled'].down_b / max(polls, 1):.0f} B per poll; "
        f"{use['polled']}; exit {polled_code}",
        f"full stream: {pcts(f.ages)}; truth frames shown {f.count}, newest "
        f"t={f.last_stamp:.2f} s; {use['full']}; exit {full_code}",
    ]
    print("\n".join(report))
    msg = "\n".join(report) + f"\nmonitor stderr:\n{polled.stderr}"
    assert polled_code == 0, msg  # it saw the run end
    assert p.joined, msg
    # it followed the vehicle to the end: about one update per 0.5 s of the mission
    assert p.last_stamp >= RUN_S - 1.0 and len(p.ages) >= 0.6 * RUN_S / 0.5, msg
    a = np.asarray(p.ages)
    assert np.percentile(a, 95) <= MAX_AGE_S and a.max() <= MAX_AGE_S, msg
    # the premise: its data crossed the shaped link, no faster than the shaper lets it
    # (rate x window + one 4 kB burst)
    assert use["polled"].down_b > 10_000, msg
    assert use["polled"].down_kbit_s <= RATE_KBIT * 1.05, msg


@dataclass
class LinkUse:
    """What a monitor's link carried during the mission, and its shaper's counters."""

    down_b: int  # run -> monitor
    up_b: int
    down_kbit_s: float
    up_kbit_s: float
    shaper: Tbf  # of the run's end (run -> monitor)

    @classmethod
    def of(cls, v: Veth, before: tuple[int, int], after: tuple[int, int], s: float) -> LinkUse:
        down, up = after[0] - before[0], after[1] - before[1]
        return cls(down, up, 8e-3 * down / s, 8e-3 * up / s, tbf(v.ns_a, v.dev_a))

    def __str__(self) -> str:
        t = self.shaper
        return (
            f"{self.down_kbit_s:.1f} kbit/s run->monitor, {self.up_kbit_s:.1f} back; "
            f"shaper sent {t.sent_bytes} B, dropped {t.dropped} packets, {t.overlimits} overlimits"
        )


def _bytes(v: Veth) -> tuple[int, int]:
    """(tx, rx) of the run's end of a monitor's link."""
    return link_bytes(v.ns_a, v.dev_a)
