"""Benchmark the runtimes against baselines measured in the same run.

1. lockstep vs inproc wall time for the same default mission (target: lockstep <= 3x);
2. lockstep real-time factor on the default mission (target: >= 20x faster than real time);
3. realtime control-loop latency with a zero-delay profile: sensor sample to command applied
   at the plant, through sensor -> filter -> controller -> plant (three Zenoh hops via the
   router, event-driven cores), against the raw Zenoh one-way hop latency measured here.
"""

from __future__ import annotations

import argparse
import logging
import statistics
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from common.config.scenario import load_scenario
from common.messages import VehicleStatus
from common.runtime.inproc import run_inproc
from common.runtime.lockstep import run_lockstep
from common.runtime.realtime import run_realtime

ROOT = Path(__file__).resolve().parents[1]
LOOP_TOML = """
[run]
mission = "common.runtime.testloop:TestLoop"
max_time_s = {seconds}
[testloop]
event_driven = true
"""


class _LoopTimer(logging.Handler):
    """Catches the coordinator's 'ended ... in X s wall' line: the tick loop alone."""

    def __init__(self) -> None:
        super().__init__()
        self.loop_s = float("nan")

    def emit(self, record: logging.LogRecord) -> None:
        msg = record.getMessage()
        if " s wall" in msg:
            self.loop_s = float(msg.split(" in ")[1].split(" s wall")[0])


def bench_lockstep(seed: int) -> dict[str, float]:
    s, raw = load_scenario(ROOT / "configs" / "default.toml", seed=seed)
    t0 = time.perf_counter()
    ref = run_inproc(s)
    inproc_s = time.perf_counter() - t0
    timer = _LoopTimer()
    logging.getLogger("tidelink.lockstep").addHandler(timer)
    logging.getLogger("tidelink.lockstep").setLevel(logging.INFO)
    t0 = time.perf_counter()
    got = run_lockstep(s, raw)
    lockstep_s = time.perf_counter() - t0
    assert got.metrics["trajectory_sha256"] == ref.metrics["trajectory_sha256"]
    return {
        "mission_s": ref.t_end,
        "inproc_s": inproc_s,
        "lockstep_s": lockstep_s,
        "lockstep_loop_s": timer.loop_s,
        "ticks": float(got.ticks),
    }


def raw_hop_latency_us(n: int = 2000) -> tuple[float, float]:
    """One-way latency of raw zenoh-python between two processes (bench_bus's baseline)."""
    code = ROOT / "scripts" / "_raw_hop.py"
    out = subprocess.run(
        [sys.executable, str(code), str(n)], capture_output=True, text=True, check=True, timeout=120
    )
    p50, p99 = (float(v) for v in out.stdout.split())
    return p50, p99


def bench_realtime_latency(seconds: float) -> tuple[float, float, int]:
    tmp = Path("/tmp/tidelink-bench-loop.toml")
    tmp.write_text(LOOP_TOML.format(seconds=seconds))
    s, raw = load_scenario(tmp)
    r = run_realtime(s, raw)
    ages = np.array(
        [m.command_age for m in r.record.stream("plant", "status") if isinstance(m, VehicleStatus)]
    )
    return float(np.percentile(ages, 50) * 1e6), float(np.percentile(ages, 99) * 1e6), len(ages)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--realtime-s", type=float, default=20.0)
    a = p.parse_args()
    rows = [bench_lockstep(seed) for seed in range(1, a.seeds + 1)]
    med = {k: statistics.median(r[k] for r in rows) for k in rows[0]}
    print(
        f"default mission: {med['mission_s']:.1f} s simulated, {med['ticks']:.0f} ticks "
        f"(median of {a.seeds} seeds; lockstep hash == inproc hash every time)"
    )
    print(
        f"  inproc wall           {med['inproc_s']:7.2f} s   real-time factor "
        f"{med['mission_s'] / med['inproc_s']:6.1f}x"
    )
    print(
        f"  lockstep wall (total) {med['lockstep_s']:7.2f} s   real-time factor "
        f"{med['mission_s'] / med['lockstep_s']:6.1f}x   ratio to inproc "
        f"{med['lockstep_s'] / med['inproc_s']:.2f}x  (target <= 3x)"
    )
    print(
        f"  lockstep tick loop    {med['lockstep_loop_s']:7.2f} s   real-time factor "
        f"{med['mission_s'] / med['lockstep_loop_s']:6.1f}x  (target >= 20x; excludes process"
        f" start-up), {1e3 * med['lockstep_loop_s'] / med['ticks']:.2f} ms per tick"
    )
    raw50, raw99 = raw_hop_latency_us()
    rt50, rt99, n = bench_realtime_latency(a.realtime_s)
    print(f"realtime control loop, zero-delay profile ({n} commands):")
    print(f"  sensor sample -> command applied  p50 {rt50:8.0f} us   p99 {rt99:8.0f} us")
    print(f"  raw zenoh one-way hop (baseline)  p50 {raw50:8.0f} us   p99 {raw99:8.0f} us")
    print(
        f"  loop / (3 raw hops)               p50 {rt50 / (3 * raw50):8.2f}x  p99 "
        f"{rt99 / (3 * raw99):8.2f}x"
    )


if __name__ == "__main__":
    main()
