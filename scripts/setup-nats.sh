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
. "$(dirname "$0")/lib-apt.sh"
apt_install setup-nats "the NATS tests will skip" nats-server
exit 0
