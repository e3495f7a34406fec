#!/usr/bin/env bash
# Install the dashboard's npm packages (frontend/package-lock.json) into frontend/node_modules. Idempotent.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/ensure_debian.sh npm npm
cd frontend
if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
  echo "Installing the dashboard's npm packages (npm ci) ..." >&2
  npm ci --no-audit --no-fund --loglevel=error --update-notifier=false
fi
