"""`tidelink network-report`: the networked-control sweeps, run on the sweep engine.

networked runs the four fault sweeps (delay, loss, burst, outage) with command sequences on
and off; sequence_cost measures what a sequence costs; report writes REPORT.md from small
builders.
"""

# what other packages (the CLI, scripts) may import, by module
INTERFACE: dict[str, tuple[str, ...]] = {
    "networked": ("SWEEPS", "NetworkOptions", "network_report"),
    "sequence_cost": ("CONTROLLERS", "DEFAULT_SCENARIO", "cost_table"),
}
