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
SUDO=""
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; else
    fail "not root and no sudo: cannot install tmux (the screen's size test will skip)"
  fi
fi
export DEBIAN_FRONTEND=noninteractive
if ! { $SUDO apt-get update -qq && $SUDO apt-get install -y -qq --no-install-recommends tmux; } >&2; then
  fail "apt-get install tmux failed (the screen's size test will skip)"
fi
command -v tmux >/dev/null 2>&1 || fail "tmux installed but not on PATH (the screen's size test will skip)"
