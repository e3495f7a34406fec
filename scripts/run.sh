#!/usr/bin/env bash
# Install what is missing and run QuasiTune on its embedded defaults: the dashboard and API on http://127.0.0.1:8000
# with an SQLite file in the per-user data directory (~/.local/share/quasitune, or $QUASITUNE_DATA_DIR) and the
# default model trained on the shipped real gait data. On an empty database it creates the user 'prosthetist'
# and prints its one-time password. Extra arguments go to 'quasitune serve', e.g.
#   bash scripts/run.sh --port 8080 --data-dir /srv/quasitune
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_venv.sh
bash scripts/setup_frontend.sh
exec .venv/bin/quasitune serve "$@"
