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
  # uv (PyPI) resolves and installs the same packages from the same index as pip, in parallel: about 10 s on a fresh
  # machine instead of pip's 40 (CI installs on every run); pip does it where uv cannot be had
  if ! { { .venv/bin/python -m pip install uv && .venv/bin/uv pip install --python .venv/bin/python -e ".[dev]"; } ||
         { .venv/bin/python -m pip install --upgrade pip && .venv/bin/python -m pip install -e ".[dev]"; }; } \
       > "$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "installation failed; full log in $log" >&2
    exit 1
  fi
  touch "$stamp"
fi
