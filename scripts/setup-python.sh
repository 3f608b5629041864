#!/usr/bin/env bash
# Idempotent: a small venv with pymavlink, the independent ground-station peer the tests
# talk to (and the parser the benchmark compares against), and pyulog, the independent
# ULog reader, and LightGBM, the evaluator the CPU path's trees are checked against, and NASA's
# ProgPy, the independent battery models (scripts/battery/progpy_flights.py, tests/it/energy_progpy.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-py
PY=${PYTHON:-python3}
if "$VENV/bin/python" -c 'import pymavlink, pyulog, lightgbm, progpy' 2>/dev/null; then exit 0; fi
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -r scripts/requirements-test.txt
