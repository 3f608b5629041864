#!/usr/bin/env bash
# Install mdbook (the docs book's builder) from crates.io into .tools/ — idempotent.
# `make docs` runs this first; a second run does nothing once .tools/bin/mdbook is that version.
# MDBOOK_VERSION may pin another 0.4.x; the book uses the 0.4 configuration format.
set -euo pipefail
cd "$(dirname "$0")/.."
MDBOOK_VERSION="${MDBOOK_VERSION:-0.4.52}"
# Installed already, at this version: nothing to do (another version is replaced).
if [[ -x .tools/bin/mdbook ]] && [[ "$(.tools/bin/mdbook --version 2>/dev/null)" == "mdbook v$MDBOOK_VERSION" ]]; then
    exit 0
fi
echo "setup-mdbook: installing mdbook $MDBOOK_VERSION into .tools/ (a few minutes, once)" >&2
# Only the `search` feature: the book is built, not served, so `serve`/`watch`
# (tokio, axum, notify) would only lengthen the build.
nice cargo install mdbook --locked --version "$MDBOOK_VERSION" --root .tools \
    --no-default-features --features search
