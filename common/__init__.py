"""Shared foundation: wire messages, bus, network model, runtimes, config."""

import os

# One BLAS thread per process, set before numpy loads (a setting of the user's own wins).
# tidelink runs many processes (a fleet: 16 services, the router, the launcher) on few cores,
# and its matrices are small: OpenBLAS's default, a thread per core in every process, spun
# on the cores between calls (docs/notes/0010-one-blas-thread-per-process.md).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
