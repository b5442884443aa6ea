#!/usr/bin/env bash
# Set up the project's virtual environment (idempotent) and run one job.
#   bash scripts/dev.sh run    set up, then run the main job (the sim-mode scanner graph)
#   bash scripts/dev.sh test   set up with test extras, then lint (ruff), type-check (mypy) and run the test suite
# Needs Python 3.11 and, for open3d, the system library libusb-1.0-0 (installed here when run as root).
set -euo pipefail
cd "$(dirname "$0")/.."
job="${1:-run}"

python="${PYTHON:-python3.11}"
command -v "$python" >/dev/null || python=python3
"$python" -c 'import sys; sys.exit(0 if sys.version_info[:2] == (3, 11) else 1)' \
  || { echo "dptpu needs Python 3.11; $python is $("$python" --version 2>&1)" >&2; exit 2; }

if ! ldconfig -p 2>/dev/null | grep -q 'libusb-1.0.so.0'; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
    echo "installing libusb-1.0-0 (needed by open3d)"
    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libusb-1.0-0 >/dev/null
  else
    echo "open3d needs the system library libusb-1.0-0: run 'sudo apt-get install libusb-1.0-0'" >&2
    exit 2
  fi
fi

[ -x .venv/bin/python ] || "$python" -m venv .venv
pip() { .venv/bin/python -m pip --disable-pip-version-check -q "$@"; }

case "$job" in
  run)
    pip install -e . --config-settings editable_mode=strict
    shift || true
    # the sim-mode scanner graph; with no arguments 20 scans, then a clean stop (scans:=0 runs until Ctrl-C)
    [ "$#" -gt 0 ] || set -- scans:=20
    exec .venv/bin/dptpu launch launch/sim_rig.yaml "$@"
    ;;
  test)
    # torch: training only; exactly 2.13.0, a CPU build pip takes from local disk (never an unpinned torch)
    pip install -e '.[test]' torch==2.13.0 --config-settings editable_mode=strict
    # the Blender renderer's own venv (bpy 4.5 pins numpy < 2): .blender-venv/ or $DPTPU_BLENDER_ENV; idempotent
    .venv/bin/python -m dptpu.sim.blender
    # headless Chromium for the browser viewer's test (Debian's package; the test skips with a reason without it)
    if [ ! -x /usr/bin/chromium ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null; then
      echo "installing chromium (browser viewer test)"
      apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null \
        || echo "could not install chromium: the browser viewer test will skip" >&2
    fi
    shift || true
    # lint and types first (configured in pyproject.toml): a finding stops the run before the tests
    echo "ruff check (lint, 120 columns)"
    .venv/bin/ruff check .
    echo "mypy (types of every code folder, read through the installed package)"
    .venv/bin/mypy
    exec .venv/bin/python -m pytest -q "$@"
    ;;
  *)
    echo "usage: bash scripts/dev.sh run|test [args...]" >&2
    exit 2
    ;;
esac
