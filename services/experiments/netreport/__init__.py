"""`tidelink network-report`: the networked-control sweeps, run on the sweep engine.

networked runs the four fault sweeps (delay, loss, burst, outage) with command sequences on
and off; sequence_cost measures what a sequence costs; goals judges the issue's goals and
each controller's cliff on the cells; report writes REPORT.md from small builders over the
fixed wording (wording.py).
"""

# what other packages (the CLI, scripts) may import, by module
INTERFACE: dict[str, tuple[str, ...]] = {
    "networked": ("SWEEPS", "NetworkOptions", "network_report"),
    "sequence_cost": ("CONTROLLERS", "DEFAULT_SCENARIO", "cost_table"),
}
