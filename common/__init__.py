"""Shared foundation: wire messages, bus, network model, runtimes, config."""

import os

# One BLAS thread per process, set before numpy loads (a setting of the user's own wins).
# tidelink runs many processes (a fleet: 16 services, the router, the launcher) on few cores,
# and its matrices are small: OpenBLAS's default, a thread per core in every process, spun
# on the cores between calls. Measured on 2 cores, realtime fleet4 (seeds 1-8): the CPU busy
# 85-90 % -> ~70 %; replans over 2 s: 37 -> 24, 7.6 -> 3.5 s on average, the longest 18 -> 6 s.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
