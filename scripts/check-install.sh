#!/usr/bin/env bash
# `cargo install --path .` into a temporary root, then the installed binary plans the demo
# from `/` and must give the checkout's JSON byte for byte (the shipped models and the M100's
# calibration are compiled in: docs/src/user-guide.md, "The same figures from any directory").
# Usage: scripts/check-install.sh [--release]   (default: the dev profile, reusing target/)
set -euo pipefail
root="$(cd "$(dirname "$0")/.." && pwd)"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
profile=(--debug)
[[ "${1:-}" == "--release" ]] && profile=()
CARGO_TARGET_DIR="$root/target" cargo install --path "$root" --locked "${profile[@]}" \
    --bin dronewatt --root "$tmp/root" --quiet
export DRONEWATT_HOME=off XDG_CACHE_HOME="$tmp/cache" RUST_LOG=warn
plan="$root/replay/demo.plan"
(cd / && "$tmp/root/bin/dronewatt" plan "$plan" --json -) > "$tmp/installed.json"
(cd "$root" && cargo run -q --bin dronewatt -- plan "$plan" --json -) > "$tmp/checkout.json"
if cmp -s "$tmp/installed.json" "$tmp/checkout.json"; then
    echo "ok: the installed dronewatt plans from / as the checkout does ($(grep -o '"margin_p50_wh": [0-9.-]*' "$tmp/installed.json" | head -1))"
else
    diff "$tmp/checkout.json" "$tmp/installed.json" | head -20
    echo "FAIL: the installed dronewatt's plan differs" >&2
    exit 1
fi
