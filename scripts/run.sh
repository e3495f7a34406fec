#!/usr/bin/env bash
# Install what is missing and run QuasiTune's main job on its embedded defaults.
# Until the server exists (issue 4) that is a proposal for a nominal task from the default model,
# trained on the shipped real gait data. Extra arguments replace the default task, e.g.
#   bash scripts/run.sh --speed 1.6 --incline 5 --mass 82
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup_venv.sh
if [ "$#" -eq 0 ]; then set -- --speed 1.25 --incline 0 --mass 75; fi
exec .venv/bin/quasitune predict "$@"
