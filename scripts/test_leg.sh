#!/usr/bin/env bash
# The leg's environment (issue 54): .venv-leg holds the leg extra alone (.[leg]: numpy, pydantic, python-can, cantools,
# paho-mqtt and the Open Source Leg SDK, with the SDK's own pins: numpy<2, pandas<3), never the server's or the model's
# packages. This installs it if missing, checks that `quasitune leg` runs from it, then adds what the tests need
# (pytest, MuJoCo for the bench behind the SDK's interfaces, the SDK's Dephy extra) and runs tests/leg there.
#   bash scripts/test_leg.sh [pytest arguments]      (scripts/test.sh runs it after the main suite)
#   bash scripts/test_leg.sh --install               only make the environment (scripts/test.sh: while it sets up)
set -euo pipefail
cd "$(dirname "$0")/.."
install_only=0
if [ "${1:-}" = "--install" ]; then install_only=1; shift; fi
PY=${PYTHON:-python3}
if [ ! -x .venv-leg/bin/python ]; then
  "$PY" -m venv .venv-leg
fi
stamp=.venv-leg/.quasitune-installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  log=.venv-leg/install.log
  {
    if [ -x .venv/bin/uv ]; then install=(.venv/bin/uv pip install --python .venv-leg/bin/python)
    else .venv-leg/bin/python -m pip install --upgrade pip; install=(.venv-leg/bin/python -m pip install); fi
    "${install[@]}" -e ".[leg]"
    # the leg's command from the leg's packages alone, before the tests bring MuJoCo
    .venv-leg/bin/quasitune leg --help > /dev/null
    .venv-leg/bin/python -c "import numpy, sys; sys.exit(0 if numpy.__version__ < '2' else 1)"
    # the tests also exercise the SDK's real Dephy actuator class (flexsea), which a Dephy leg installs anyway
    "${install[@]}" "pytest>=8" "pytest-timeout>=2.3" "pytest-xdist>=3.5" "mujoco>=3.1" "opensourceleg[dephy]>=3.5,<4"
  } > "$log" 2>&1 || { tail -n 40 "$log" >&2; echo "the leg's environment could not be made; log in $log" >&2; exit 1; }
  touch "$stamp"
fi
if ! .venv-leg/bin/python -c "import xdist" 2> /dev/null; then   # an environment made before the tests ran in two
  .venv-leg/bin/python -m pip install -q "pytest-xdist>=3.5" > /dev/null
fi
if [ "$install_only" -eq 1 ]; then exit 0; fi
# tests/conftest.py is the server's (its fixtures import the backend): the leg's tests bring their own helpers; two
# processes, each taking the next test as it frees up (four walks on the leg's simulated clock are most of the time)
exec .venv-leg/bin/python -m pytest -q -p no:cacheprovider --noconftest -n 2 --dist worksteal tests/leg "$@"
