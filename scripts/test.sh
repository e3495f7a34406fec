#!/usr/bin/env bash
# Install what is missing, then run the linter and the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_venv.sh
bash scripts/setup_frontend.sh
# the browser tests drive Debian's Chromium (never 'playwright install'); docker-compose checks the compose file
bash scripts/ensure_debian.sh chromium chromium docker-compose docker-compose
.venv/bin/ruff check .
exec .venv/bin/python -m pytest -q "$@"
