#!/usr/bin/env bash
# Idempotent: Debian's NATS server (2.9; JetStream with `-js`), for the fleet's NATS tests
# (tests/it/fleet_nats.rs) and the demo. The tests start their own server on a free
# loopback port with a throwaway store and config; nothing here starts or enables a
# system service.
# Without root or network this fails and says so; the NATS tests then skip, except under
# CI=true, where a missing server fails them.
set -uo pipefail
if command -v nats-server >/dev/null 2>&1 || [ -x /usr/bin/nats-server ] || [ -x /usr/sbin/nats-server ]; then
  exit 0
fi
SUDO=""
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; else
    echo "setup-nats: not root and no sudo: cannot install nats-server (the NATS tests will skip)" >&2
    exit 0
  fi
fi
export DEBIAN_FRONTEND=noninteractive
# Only refresh the package lists when the package is unknown (a fresh container).
if ! apt-cache show nats-server >/dev/null 2>&1; then
  $SUDO apt-get update -qq >&2 || true
fi
if ! $SUDO apt-get install -y -qq --no-install-recommends nats-server >&2; then
  echo "setup-nats: apt-get install nats-server failed (the NATS tests will skip)" >&2
fi
exit 0
