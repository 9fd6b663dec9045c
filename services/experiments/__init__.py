"""Network-fault experiments: resumable sweeps over scenario grids, and the paper's comparison.

Modules: schema (experiment files), grid (runs and their ids), worker (one run anywhere),
execute (here, a process pool or Dask), results (results.csv), stats, summary, plots,
sweep (the whole sweep), tuning, claims, report, figures and reproduce (`tidelink reproduce`).
Nothing is imported here, so a pool or Dask worker loads only what a run needs.
"""
