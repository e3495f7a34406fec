#!/usr/bin/env bash
# Install what is missing, then run the linter and the whole test suite.
#   bash scripts/test.sh            the whole suite (CI runs this through .ci/run), with the leg's environment's beside it
#   bash scripts/test.sh --fast     everything but the browser, PostgreSQL, broker and wall-clock tests (work in progress)
# Further arguments go to pytest (a path, -k, -x ...).
set -euo pipefail
cd "$(dirname "$0")/.."
fast=0
if [ "${1:-}" = "--fast" ]; then fast=1; shift; fi
# the Debian packages, then the dashboard's npm packages (apt, then npm: one after the other, one package manager at a
# time), are made beside the Python environment (uv): neither needs the other, and on a fresh machine each takes tens of
# seconds. The browser tests drive Debian's Chromium, its headless shell (tests/helpers/browser.py; never 'playwright
# install'); docker-compose checks the compose file; the store, router and concurrency tests also run on PostgreSQL: a
# throwaway server the tests start themselves from Debian's binaries (tests/helpers/postgres.py), on loopback, in a
# temporary folder, as 'nobody' under root; the broker link's tests start Mosquitto likewise (tests/helpers/
# mosquitto.py: TLS with a CA made by openssl for the run)
system_log=$(mktemp -t quasitune-system-XXXXXX.log)
{
  if [ "$fast" -eq 0 ]; then
    bash scripts/ensure_debian.sh chromium-headless-shell chromium-headless-shell docker-compose docker-compose \
        pg_ctlcluster postgresql mosquitto mosquitto mosquitto_ctrl mosquitto-clients openssl openssl
  fi
  bash scripts/setup_frontend.sh
} > "$system_log" 2>&1 &
system_install=$!
bash scripts/setup_venv.sh
# the leg's own environment (scripts/test_leg.sh: the Open Source Leg SDK pins numpy<2) is made while the rest sets up
if [ "$fast" -eq 0 ] && [ "$#" -eq 0 ]; then
  leg_log=$(mktemp -t quasitune-leg-XXXXXX.log)
  bash scripts/test_leg.sh --install > "$leg_log" 2>&1 &
  leg_install=$!
fi
system_status=0
wait "$system_install" || system_status=$?
cat "$system_log" >&2; rm -f "$system_log"
if [ "$system_status" -ne 0 ]; then echo "the Debian or npm packages could not be installed (above)" >&2; exit 1; fi
.venv/bin/ruff check .
# one fit of the default model for every process of the run (the first to need it fits and caches it, the others wait
# for it: controller_core/model_io.py); --fast keeps it between runs (the cache is keyed by the data's and the code's
# hashes, so a changed model is fitted again)
if [ "$fast" -eq 1 ] && [ -z "${QUASITUNE_CACHE_DIR:-}" ]; then
  export QUASITUNE_CACHE_DIR="${XDG_CACHE_HOME:-$HOME/.cache}/quasitune-tests"
elif [ -z "${QUASITUNE_CACHE_DIR:-}" ]; then
  QUASITUNE_CACHE_DIR=$(mktemp -d -t quasitune-test-cache-XXXXXX)
  trap 'rm -rf "$QUASITUNE_CACHE_DIR"' EXIT
  export QUASITUNE_CACHE_DIR
fi
# bytecode written where Python writes it (.venv, the repository's __pycache__, both ignored by git), even where the
# environment says not to: each module a test process, server or command imports is then compiled once for the whole
# run instead of once per process, and pytest keeps its rewritten test modules (scripts/setup_venv.sh compiles only
# what a server imports)
unset PYTHONDONTWRITEBYTECODE
# one BLAS/OpenMP thread per process: test processes on a 2-core machine each spinning two math threads ran the
# model's fits several times slower than one process alone (the server does the same: backend/serve.py)
export OMP_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 MKL_NUM_THREADS=1
# the plugins the suite uses, named: pytest rewrites the asserts of every module of an auto-loaded plugin's package,
# and anyio's and hypothesis's (whole libraries the suite imports anyway) cost each test process 2 s of that
pytest=(.venv/bin/python -m pytest -q --disable-plugin-autoload -p xdist.plugin -p pytest_timeout
        -p _hypothesis_pytestplugin)
if [ "$fast" -eq 1 ]; then     # CPU-bound tests: one process per core, each taking the next test as it frees up
  exec "${pytest[@]}" -n 2 --dist worksteal -m "not browser and not postgres and not broker and not wallclock" "$@"
fi
# the whole suite: three processes on two cores, because a third of the browser, server and broker tests' time is
# spent waiting (a page, a real-time leg, a broker); each process takes whole files (`--dist loadfile`: a file's server
# or browser is started once), the files with servers, browsers, brokers and PostgreSQL first (tests/conftest.py) so
# that short files fill the end
if [ -n "${leg_install:-}" ] && ! wait "$leg_install"; then
  cat "$leg_log"; echo "the leg's environment (scripts/test_leg.sh) could not be made" >&2; exit 1
fi
# the leg's tests in their environment run beside the main suite at the lowest CPU priority (nice 19): they take only
# what the main suite leaves (its waits for pages, real-time legs and brokers), then the whole machine once it ends.
# At the same priority they slowed its wall-clock tests by more than their own time; after it, they added 15-20 s.
# Each test's time limit is longer there (900 s, pyproject's 120 s otherwise): a test may wait for the CPU until the
# main suite ends, since it gets almost none while both cores are busy (a brand-new clone: the leg's 17 tests in
# 48-67 s beside it, and the whole run 296-323 s against 329-340 s)
if [ -n "${leg_install:-}" ]; then
  nice -n 19 bash scripts/test_leg.sh --timeout 900 > "$leg_log" 2>&1 &
  leg_tests=$!
fi
status=0
"${pytest[@]}" -n 3 --dist loadfile --no-loadscope-reorder "$@" || status=$?
if [ -n "${leg_install:-}" ]; then
  leg_status=0
  wait "$leg_tests" || leg_status=$?
  echo "the leg's environment (scripts/test_leg.sh):"
  cat "$leg_log"
  rm -f "$leg_log"
  if [ "$leg_status" -ne 0 ]; then status=1; fi
fi
exit "$status"
