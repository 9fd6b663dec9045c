"""A tidelink process runs one BLAS thread (numpy's OpenBLAS) unless its user says otherwise."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

# Asks the OpenBLAS that numpy loaded how many threads it runs (its symbol names carry
# the scipy-openblas build's prefix; a numpy on another BLAS is reported as such)
PROBE = """
import ctypes
import services.cli  # the tidelink command's first import, before it loads numpy
import numpy
libs = sorted({l.split()[-1] for l in open("/proc/self/maps") if "openblas" in l})
if not libs:
    print("no-openblas")
else:
    lib = ctypes.CDLL(libs[0])
    for name in ("scipy_openblas_get_num_threads64_", "openblas_get_num_threads"):
        if hasattr(lib, name):
            print(getattr(lib, name)())
            break
    else:
        print("unknown-openblas")
"""


def _threads(env: dict[str, str]) -> str:
    res = subprocess.run(
        [sys.executable, "-c", PROBE],
        cwd=REPO,
        env=env,
        capture_output=True,
        text=True,
        timeout=60,
        check=True,
    )
    return res.stdout.strip()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc/self/maps")
def test_one_blas_thread_by_default_and_the_users_setting_wins() -> None:
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}
    got = _threads(env)
    if got in ("no-openblas", "unknown-openblas"):
        pytest.fail(f"numpy's BLAS is not the OpenBLAS this test knows: {got}")
    assert got == "1"
    assert _threads({**env, "OPENBLAS_NUM_THREADS": "2"}) == "2"


def test_numpy_loaded_before_common_is_warned_of() -> None:
    """Too late to set the threads: a script that imports numpy first is told so (a chaotic
    run, ocean.toml's, then ends differently from `tidelink run`'s)."""
    env = {k: v for k, v in os.environ.items() if k != "OPENBLAS_NUM_THREADS"}

    def warned(code: str, **extra: str) -> bool:
        res = subprocess.run(
            [sys.executable, "-W", "always", "-c", code],
            cwd=REPO,
            env={**env, **extra},
            capture_output=True,
            text=True,
            timeout=60,
            check=True,
        )
        return "numpy was imported before tidelink's `common`" in res.stderr

    assert warned("import numpy; import common")
    assert not warned("import common; import numpy")
    assert not warned("import numpy; import common", OPENBLAS_NUM_THREADS="1")
