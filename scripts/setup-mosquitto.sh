#!/usr/bin/env bash
# Idempotent: Debian's Mosquitto broker and its command-line clients, for the MQTT sink's
# tests (tests/it/sink_mqtt/). The tests start their own broker on a free loopback port
# with a throwaway config; nothing here starts or enables a system service.
# Without root or network this fails and says so; the MQTT tests then skip, except
# under CI=true, where a missing broker fails them.
set -uo pipefail
if command -v mosquitto >/dev/null 2>&1 || [ -x /usr/sbin/mosquitto ]; then
  if command -v mosquitto_sub >/dev/null 2>&1; then exit 0; fi
fi
. "$(dirname "$0")/lib-apt.sh"
apt_install setup-mosquitto "the MQTT tests will skip" mosquitto mosquitto-clients
exit 0
