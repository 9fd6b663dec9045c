"""Network-fault experiments: the sweep engine, the paper's reproduction, the network report.

Three packages, imports running one way (reproduction and netreport on sweep, never back):

    sweep/          resumable sweeps over scenario grids: results.csv, summary.md, plots
    reproduction/   `tidelink reproduce`: the paper's section-4 comparison and its REPORT.md
    netreport/      `tidelink network-report`: the networked-control sweeps and their REPORT.md

Each package's `__init__.py` names its interface (INTERFACE: module -> the names other
packages may import). Nothing is imported here, so a pool or Dask worker loads only what a
run needs.
"""
