#!/usr/bin/env bash
# The test command: set up (idempotent), then lint, type-check and run the whole suite.
#   bash scripts/test.sh          everything (what .ci/run runs)
#   bash scripts/test.sh --fast   lint, types, and the unit and read-back tests: no simulation,
#                                 no end-to-end job, no headless viewer (the loop while coding)
# Further arguments go to pytest (e.g. `bash scripts/test.sh --fast -k memory`).
set -euo pipefail
cd "$(dirname "$0")/.."
lane=()
if [ "${1:-}" = "--fast" ]; then
  shift
  # two workers (pytest-xdist), the machine's two cores; the tests that fit a memory map on one of them
  # (tests/conftest.py, MAP_FILES)
  lane=(-m "not slow and not viewer" -n 2 --dist loadgroup)
  # The tests write ~300 MB of small files a run: in memory where there is /dev/shm, so the loop does not
  # wait on a busy disk (51-52 s against 60-66 s on this machine's disk while it was throttled). pytest
  # empties that folder at the next run's start; a failed test's files stay there till then.
  if [ -d /dev/shm ] && [ -w /dev/shm ]; then
    lane+=(--basetemp "/dev/shm/robofailring-fast-$(id -u)-$(pwd | cksum | cut -d' ' -f1)")
  fi
fi
bash scripts/setup.sh --dev
export ROBOFAILRING_PROGRESS=0
# Bytecode on (__pycache__ is gitignored), whatever the shell set: without it every worker re-compiles
# and re-rewrites the assertions of every test module at collection, ~9 s of each run on 2 cores.
unset PYTHONDONTWRITEBYTECODE
# setup.sh --dev installed the viewer's driver, ffmpeg and Chromium: a test that misses one fails
# (tests/environment.py); a plain local `pytest` skips it instead.
export ROBOFAILRING_FULL_ENV=1
.venv/bin/ruff check .
.venv/bin/ruff format --check .
.venv/bin/mypy
.venv/bin/python -m pytest -q "${lane[@]}" "$@"
