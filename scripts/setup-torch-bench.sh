#!/usr/bin/env bash
# Idempotent: PyTorch eager from PyPI in its own venv, for the LSTM side-by-side
# (`scripts/bench_torch.py`). Not part of `make test`: PyPI's Linux wheel of torch 2.13.0
# pulls its CUDA libraries (about 4 GB; no GPU needed to run on the CPU). The libtorch that
# dronewatt links (`.venv-torch`, scripts/setup-libtorch.sh) stays a separate, small venv.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-bench
PY=${PYTHON:-python3}
if "$VENV/bin/python" -c 'import torch, numpy' 2>/dev/null; then exit 0; fi
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check torch==2.13.0 numpy
