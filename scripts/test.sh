#!/usr/bin/env bash
# Install what is missing, then run the linter and the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_venv.sh
.venv/bin/ruff check .
exec .venv/bin/python -m pytest -q "$@"
