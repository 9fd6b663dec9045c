"""Runtimes that host service cores, in three layers.

- `model`: the pure scheduling model (core contract, declared dataflow, Host, record,
  run result, mission, the inproc runtime). No Zenoh, no processes, no wall clock.
- `distributed`: the Zenoh runtimes built on it: the lockstep coordinator, the realtime
  driver and mission clock, and the service process that hosts one core.
- `processes`: OS process management: the fork server, child processes, supervision
  with restart policies, and signal handling.

`common.runtime.run` dispatches a scenario to the runtime it names.
"""
