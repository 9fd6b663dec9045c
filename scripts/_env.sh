# Shared by scripts/run and scripts/test: make sure .venv exists and holds this project.
# (Re)installs when the venv is missing, or pyproject.toml changed since the last install.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
VENV="$ROOT/.venv"
STAMP="$VENV/.tidelink-installed"
PY="${PYTHON:-python3}"

if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)' 2>/dev/null; then
  echo "tidelink needs Python >= 3.11 (found: $("$PY" --version 2>&1)); set PYTHON=/path/to/python3.11" >&2
  exit 1
fi
# a run starts dozens of Python processes (services, routers, tools, test workers): each one
# compiled every module from source again where the environment forbids bytecode caches
unset PYTHONDONTWRITEBYTECODE
if [ ! -x "$VENV/bin/python" ]; then
  echo "== creating virtual environment in .venv"
  # without pip (ensurepip takes seconds): uv installs into it, pip only if uv cannot
  "$PY" -m venv --without-pip "$VENV"
fi
if [ ! -f "$STAMP" ] || [ "$ROOT/pyproject.toml" -nt "$STAMP" ]; then
  echo "== installing tidelink and its dependencies into .venv"
  # uv (from PyPI) fetches and installs the wheels in parallel, in seconds where pip takes
  # half a minute. No bytecode is compiled ahead: Python compiles (and caches) the modules a
  # run imports, a fraction of the environment's, on first import
  if ! { "$PY" -m pip --python "$VENV/bin/python" install --quiet uv &&
         "$VENV/bin/python" -m uv pip install --quiet --python "$VENV/bin/python" -e "$ROOT[dev]"; }
  then
    echo "== uv could not install; installing with pip"
    "$VENV/bin/python" -m ensurepip --upgrade >/dev/null
    "$VENV/bin/python" -m pip install --quiet -e "$ROOT[dev]"
  fi
  # compile (and cache) what a run imports once, here: left to the first run, every process
  # it starts at once (test workers, services) compiled the same modules again
  "$VENV/bin/python" -c 'import importlib, services.cli, matplotlib.pyplot
from common.runtime.processes.forkserver import PRELOAD
for m in (*PRELOAD, "services.experiments", "services.monitor", "services.foxglove"):
    importlib.import_module(m)'
  touch "$STAMP"
fi
export PATH="$VENV/bin:$PATH"
# one BLAS thread per process (common/__init__.py), also for the benchmarks that load numpy
# before tidelink; a setting of the user's own wins
export OPENBLAS_NUM_THREADS="${OPENBLAS_NUM_THREADS:-1}"
cd "$ROOT"
