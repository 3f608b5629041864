#!/usr/bin/env bash
# Idempotent: installs the libtorch that tch 0.26 links against (PyTorch 2.13.0's, CPU
# build is enough) into a project-local venv, and points `.libtorch` at it.
# Never install Debian's libtorch-dev beside it: its libc10.so shadows this one.
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=.venv-torch
PY=${PYTHON:-python3}
if [ -f .libtorch/lib/libtorch_cpu.so ] && "$VENV/bin/python" -c 'import torch,sys; sys.exit(torch.__version__.split("+")[0]!="2.13.0")' 2>/dev/null; then
  exit 0
fi
echo "setting up libtorch (PyTorch 2.13.0) in $VENV — about 1.2 GB, once" >&2
[ -x "$VENV/bin/python" ] || "$PY" -m venv "$VENV"
"$VENV/bin/python" -m pip install -q --disable-pip-version-check --no-deps \
  torch==2.13.0 nvidia-cuda-runtime==13.0.96 nvidia-cuda-cupti==13.0.85
SITE=$("$VENV/bin/python" -c 'import sysconfig; print(sysconfig.get_paths()["purelib"])')
ln -sfn "$(realpath --relative-to=. "$SITE/torch")" .libtorch
test -f .libtorch/lib/libtorch_cpu.so
echo "libtorch ready: $(readlink .libtorch)" >&2
