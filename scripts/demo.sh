#!/usr/bin/env bash
# The main job on the embedded default: set up (idempotent), then simulate, build the memory,
# calibrate, evaluate and write recordings under recordings/demo/. Extra arguments go to `robofailring demo`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
.venv/bin/robofailring demo "$@"
