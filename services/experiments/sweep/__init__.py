"""The sweep engine: an experiment file's grid run resumably, aggregated, tabled and drawn.

schema (the experiment file) -> grid (one scenario per cell and seed) -> execute and worker
(here, a process pool or Dask) -> results (results.csv) -> summary and stats (per cell, with
intervals) -> plots; run.run_sweep does all of it. markdown builds the blocks every report
is made of (tables, sections); labels names the controllers in reports. Nothing is imported
here: a pool or Dask worker that loads worker.py loads only what a run needs.
"""

# what the other packages (reproduction, netreport, the CLI, scripts) may import, by module
INTERFACE: dict[str, tuple[str, ...]] = {
    "schema": ("Axis", "AxisValue", "Experiment", "SetValue", "load_experiment"),
    "run": ("SweepOptions", "SweepReport", "run_sweep"),
    "results": ("as_number",),
    "stats": ("Estimate",),
    "summary": ("CellStats", "FAILURES", "aggregate", "success_text"),
    "plots": ("plot_sweep",),
    "labels": ("CONTROLLER_NAMES",),
    "markdown": ("Block", "blocks", "document", "section", "table"),
}
