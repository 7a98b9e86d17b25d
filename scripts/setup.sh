#!/usr/bin/env bash
# Set up everything the project needs on a fresh machine: a virtualenv in .venv with the package
# (and, with --dev, the test tools, ffmpeg and Chromium), plus the software Vulkan driver the headless
# Rerun viewer needs. scripts/test.sh runs this; its viewer and report tests fail where a piece is missing.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
if ! "$PYTHON" -c 'import sys; sys.exit(sys.version_info < (3, 11))' 2>/dev/null; then
  echo "error: $PYTHON is $("$PYTHON" --version 2>&1); RoboFailRing needs Python >= 3.11 (rerun-sdk 0.41 requires it)." >&2
  echo "       Install one (e.g. apt-get install python3.11 python3.11-venv) and run again with PYTHON=python3.11." >&2
  exit 2
fi
if [ ! -x .venv/bin/python ]; then
  "$PYTHON" -m venv .venv
fi
.venv/bin/python -m pip install --quiet --upgrade pip
dev=""
if [ "${1:-}" = "--dev" ]; then dev=1; fi
# Every extra (docs/install.md, "Install"), and with --dev the test tools and the docs site's (the full
# lane builds it); torch/torchvision: the registry's matching pair, pinned in constraints.txt
# (docs/install.md, "Why this torch").
.venv/bin/python -m pip install --quiet -c constraints.txt -e ".[all${dev:+,dev,docs}]"
# The Rerun viewer renders headless only with Mesa's software Vulkan driver (lavapipe).
if ! ldconfig -p 2>/dev/null | grep -q libvulkan.so.1 || [ ! -e /usr/share/vulkan/icd.d/lvp_icd.x86_64.json ]; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
      mesa-vulkan-drivers libvulkan1 >/dev/null) || echo "warning: could not install mesa-vulkan-drivers; the viewer tests will fail" >&2
  else
    echo "note: install mesa-vulkan-drivers and libvulkan1 to render recordings headless" >&2
  fi
fi
# The viewer decodes H.264 camera streams with ffmpeg (>= 5.1); the H.264 viewer test needs it.
if [ -n "$dev" ] && ! command -v ffmpeg >/dev/null && [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends ffmpeg >/dev/null) \
    || echo "warning: could not install ffmpeg; the H.264 viewer test will fail" >&2
fi
# The report test renders report.html in headless Chromium (Debian's package `chromium`).
if [ -n "$dev" ] && ! command -v chromium >/dev/null && ! command -v chromium-browser >/dev/null \
  && [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null; then
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends chromium >/dev/null) \
    || echo "warning: could not install chromium; the report.html rendering test will fail" >&2
fi
# The bench-only ManiSkill venv bench/bench_peer.py runs the peer simulator in (bench/setup_peer.sh: outside .venv,
# never the project's install), made where bench_peer.py looks for it, once: the full lane checks that its
# generator answers --help (tests/docs/test_benches.py).
if [ -n "$dev" ]; then
  PYTHONPATH=src:. .venv/bin/python -c 'from bench.bench_peer import default_peer_env, ready_peer_env; ready_peer_env(default_peer_env())' \
    || echo "warning: could not make the bench-only peer venv (bench/setup_peer.sh); the peer generator's test will fail" >&2
fi
