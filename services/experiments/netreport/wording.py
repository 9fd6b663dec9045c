"""The fixed wording of the network report's REPORT.md."""

from __future__ import annotations

from string import Template

TITLE = "Control that survives the network: command sequences, measured delay, prediction"
REGENERATE = Template(
    "Regenerate with `$command` ($runs runs, $runtime, $errors failed to run; the runs resume "
    "from the output folder)."
)
# what is compared, and on which terms
INTRO = """\
What is compared, on the default mission's field in the world above (the calm
`configs/default.toml` is the paper's), inproc, every controller on equal terms:

- **sequences on** (`controller.sequence.horizon_s = 10`, the default): packet-based
  predictive control. Each command carries the controller's commands for now and every
  0.1 s of the next 10 s, each computed on the state predicted for its time: from the
  estimate's newest fix, forward under the commands already sent (those in flight
  included) with a model of the vehicle's response (eq. (7), speed and yaw lags, R_min).
  The vehicle applies the entry for its own time from the newest command it holds, keeps
  consuming the buffer through a loss or an outage, and the last entries bring it to rest
  on its path (the stop tail) instead of running on blind into HOLD;
- **sequences off** (`horizon_s = 0`, the ablation): single commands computed as before
  sequences existed (the controller predicts the estimate forward at constant twist over
  its age plus the downlink delay).

Both measure the delay instead of assuming it (the downlink from the vehicle's status:
its median; staleness is the estimate's age beyond the delay it arrives with), so
the 'off' columns are not the old code: before issue 16 a 1 s delay made every estimate
stale and the vehicle never moved. Success = reached the goal without contact and never
inside the safety distance rho0; with 20 seeds, 95 % allows one failed run (the Wilson 95 %
interval of 19/20 is 76–99 %)."""


CLIFFS = (
    "The last fault level up to which a controller succeeds in ≥ 95 % of the runs, and "
    "the first where it does not; and its success over every level of the sweep."
)
SWEEP = Template(
    "`$file`: $x_label; $runs runs ($errors failed to run), seeds $first–$last per cell."
)
PER_CELL = (
    "Per cell, sequences on / off: success (goal, no contact, never inside rho0); the "
    "failed runs by outcome (goal reached but inside rho0 / contact / goal not reached); "
    "mean minimum clearance (m); mean cross-track error to the path in force (RMS, m); "
    "mean time in HOLD or FAILSAFE (s)."
)
COST = (
    "The planner's control step (prediction, the entries computed on the newest state, the "
    "message: what the command waits for) and, after it, its preparing the next step (the "
    "rest of the rollout over the horizon, `controller.sequence.fresh_s`), timed on this "
    "machine's CPU clock along the default mission's first plan, and the command's size "
    "on the wire (envelope included); ratios to single commands measured in the same run "
    "(`scripts/bench_sequence.py`, `services/experiments/netreport/sequence_cost.py`). The "
    "control period is 100 ms."
)
