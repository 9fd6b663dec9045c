"""Shared foundation: wire messages, bus, network model, runtimes, config."""

import os
import sys
import warnings

# One BLAS thread per process, set before numpy loads (a setting of the user's own wins).
# tidelink runs many processes (a fleet: 16 services, the router, the launcher) on few cores,
# and its matrices are small: OpenBLAS's default, a thread per core in every process, spun
# on the cores between calls (docs/notes/0010-one-blas-thread-per-process.md).
if "numpy" in sys.modules and "OPENBLAS_NUM_THREADS" not in os.environ:
    # too late for the setting: numpy's BLAS already runs a thread per core, and a matrix
    # product's last bits (and so a long run's trajectory) then differ from the CLI's
    warnings.warn(
        "numpy was imported before tidelink's `common`: its BLAS runs on several threads and "
        "runs may differ in their last bits from `tidelink run`'s; import common first, or "
        "set OPENBLAS_NUM_THREADS=1",
        RuntimeWarning,
        stacklevel=2,
    )
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
