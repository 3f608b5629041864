#!/usr/bin/env bash
# Idempotent: headless Chromium for the web dashboard test (tests/it/sink_web.rs).
# Debian's `chromium` package. Without root or network this fails and the test says so
# loudly and skips; everything else still runs. Under CI (CI=true) a missing chromium is
# an error here and in the tests: CI must not go green with the dashboard untested.
set -uo pipefail
fail() {
  echo "setup-chromium: $1" >&2
  if [ "${CI:-}" = true ] || [ "${CI:-}" = 1 ]; then
    echo "setup-chromium: CI=${CI}: the web dashboard tests need chromium; failing" >&2
    exit 1
  fi
  exit 0
}
for c in chromium chromium-browser; do
  if command -v "$c" >/dev/null 2>&1; then exit 0; fi
done
. "$(dirname "$0")/lib-apt.sh"
apt_install setup-chromium "the web test will skip" chromium ||
  fail "could not install chromium (the web test will skip)"
for c in chromium chromium-browser; do
  if command -v "$c" >/dev/null 2>&1; then exit 0; fi
done
fail "chromium installed but not on PATH (the web test will skip)"
