#!/usr/bin/env bash
# Install what is missing, then run the linter and the whole test suite.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_venv.sh
bash scripts/setup_frontend.sh
# the browser tests drive Debian's Chromium (never 'playwright install'); docker-compose checks the compose file;
# the store, router and concurrency tests also run on PostgreSQL: a throwaway server the tests start themselves from
# Debian's binaries (tests/helpers/postgres.py), on loopback, in a temporary folder, as 'nobody' under root; the broker
# link's tests start Mosquitto likewise (tests/helpers/mosquitto.py: TLS with a CA made by openssl for the run)
bash scripts/ensure_debian.sh chromium chromium docker-compose docker-compose pg_ctlcluster postgresql \
    mosquitto mosquitto mosquitto_ctrl mosquitto-clients openssl openssl
.venv/bin/ruff check .
exec .venv/bin/python -m pytest -q "$@"
