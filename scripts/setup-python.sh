#!/usr/bin/env bash
# Idempotent: a small venv with pymavlink, the independent ground-station peer the tests
# talk to (and the parser the benchmark compares against), and pyulog, the independent
# ULog reader, LightGBM, the evaluator the CPU path's trees are checked against, multirotor,
# the independent electrical peer the spec-sheet forecast is scored on, and NASA's ProgPy, the
# independent battery models (tests/peers/progpy_flights.py, tests/it/energy_progpy.rs).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-py
PY=${PYTHON:-python3}
if "$VENV/bin/python" -c 'import pymavlink, pyulog, lightgbm, multirotor, progpy' 2>/dev/null; then exit 0; fi
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check -r scripts/requirements-test.txt
