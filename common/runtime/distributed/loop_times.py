"""Where a realtime service's loop spends its time: waking late, stepping, publishing, preparing."""

from __future__ import annotations

from common.netmodel.stats import DurationHistogram

# what is timed per tick that published something, in wall seconds (scripts/bench
# runtime prints them)
#   wake     how late the loop ran the tick after it was due: after its timer (a periodic
#            step), or after the loop took the message it hands over from its inbox
#   step     Host.run_tick: hand-overs, the core's step, the link model, encoding
#   publish  the Zenoh puts of what the tick emitted
# and, after them, off the path from the tick's inputs to its outputs:
#   prepare  Host.prepare: the core's work for its next step (core.Prepares), per step
# and how many periods the loop skipped because it fell behind ("loop.skipped_periods"), and
# how many Ticks it refused for leaping its clock ahead unconfirmed ("loop.ticks_refused")
PHASES = ("wake", "step", "publish")
PREPARE = "prepare"
QUANTILES = {"p50": 0.5, "p95": 0.95}


class LoopTimes:
    """Durations of each phase of the ticks a realtime service ran; as the integer counters
    its statistics carry ("loop.step_p50_us", ...), so a run's record says where its loop's
    latency went, service by service."""

    def __init__(self) -> None:
        self._phases = {p: DurationHistogram() for p in (*PHASES, PREPARE)}
        self.skipped = 0  # periods skipped because the loop fell behind
        self.ticks_refused = 0  # Ticks that would have leapt the clock ahead, unconfirmed

    def record(self, wake_s: float, step_s: float, publish_s: float) -> None:
        """One tick's phases (s)."""
        for phase, d in zip(PHASES, (wake_s, step_s, publish_s), strict=True):
            self._phases[phase].record(max(0.0, d))

    def record_prepare(self, prepare_s: float) -> None:
        """How long the core prepared its next step after one (s)."""
        self._phases[PREPARE].record(max(0.0, prepare_s))

    def counters(self) -> dict[str, int]:
        """p50, p95 and max of each phase in microseconds; a phase never timed (before the first
        tick; prepare for a core that does not) has none; the periods skipped, if any."""
        out: dict[str, int] = {}
        for phase, h in self._phases.items():
            if h.count == 0:
                continue
            for name, q in zip(QUANTILES, h.quantiles(*QUANTILES.values()), strict=True):
                out[f"loop.{phase}_{name}_us"] = round(q * 1e6)
            out[f"loop.{phase}_max_us"] = round(h.max * 1e6)
        if self.skipped:
            out["loop.skipped_periods"] = self.skipped
        if self.ticks_refused:
            out["loop.ticks_refused"] = self.ticks_refused
        return out
