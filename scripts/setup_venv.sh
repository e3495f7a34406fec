#!/usr/bin/env bash
# Create .venv (if missing) and install QuasiTune with its dependencies from PyPI. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if ! "$PY" -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else 1)'; then
  echo "QuasiTune needs Python >= 3.11 (found $("$PY" --version 2>&1))" >&2; exit 1
fi
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
stamp=.venv/.quasitune-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  log=.venv/install.log
  echo "Installing QuasiTune and its dependencies into .venv (log: $log) ..." >&2
  # uv (PyPI) resolves and installs the same packages from the same index as pip, in parallel: about 20 s on a fresh
  # machine instead of pip's 40 (CI installs on every run); pip does it where uv cannot be had
  if ! { { .venv/bin/python -m pip install uv &&
           .venv/bin/uv pip install --python .venv/bin/python -e ".[server,view3d,dev]"; } ||
         { .venv/bin/python -m pip install --upgrade pip && .venv/bin/python -m pip install -e ".[server,view3d,dev]"; }; } \
       > "$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "installation failed; full log in $log" >&2
    exit 1
  fi
  # what a server imports, compiled to bytecode by importing it once: where PYTHONDONTWRITEBYTECODE is set, every
  # start would otherwise compile FastAPI, SQLAlchemy and SciPy again (8 s instead of 3). Only what is imported: all
  # 1.3 GB of packages (uv's --compile-bytecode) took 15 s of a fresh machine's set-up, mostly modules nothing imports
  if ! env -u PYTHONDONTWRITEBYTECODE .venv/bin/python -c "import backend.serve, backend.cli, uvicorn" >> "$log" 2>&1; then
    tail -n 20 "$log" >&2
    echo "the installed server does not import; full log in $log" >&2
    exit 1
  fi
  touch "$stamp"
fi
# the project's own modules compiled once, here: every test process, server and CLI imports them, and where
# PYTHONDONTWRITEBYTECODE is set Python would compile them again in each (a second here; unchanged files are skipped);
# the Alembic revisions too: every app start reads them all (an in-process test app 88 ms instead of 134)
.venv/bin/python -m compileall -q -j 0 backend controller_core device_bridge lab benchmarks migrations > /dev/null
