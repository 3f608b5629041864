#!/usr/bin/env bash
# Idempotent: tmux for the terminal screen's size tests (tests/it/views_pilot.rs: the screen
# at 80×24 and 120×40). Debian's `tmux` package. Without root or network this fails and the
# test says so loudly and skips; everything else still runs. Under CI (CI=true) a missing
# tmux is an error here and in the test: CI must not go green with the screen untested.
set -uo pipefail
fail() {
  echo "setup-tmux: $1" >&2
  if [ "${CI:-}" = true ] || [ "${CI:-}" = 1 ]; then
    echo "setup-tmux: CI=${CI}: the screen's size tests need tmux; failing" >&2
    exit 1
  fi
  exit 0
}
if command -v tmux >/dev/null 2>&1; then exit 0; fi
. "$(dirname "$0")/lib-apt.sh"
apt_install setup-tmux "the screen's size test will skip" tmux ||
  fail "could not install tmux (the screen's size test will skip)"
command -v tmux >/dev/null 2>&1 || fail "tmux installed but not on PATH (the screen's size test will skip)"
