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
SUDO=""
if [ "$(id -u)" != 0 ]; then
  if command -v sudo >/dev/null 2>&1; then SUDO="sudo -n"; else
    echo "setup-mosquitto: not root and no sudo: cannot install mosquitto (the MQTT tests will skip)" >&2
    exit 0
  fi
fi
export DEBIAN_FRONTEND=noninteractive
# Only refresh the package lists when the package is unknown (a fresh container).
if ! apt-cache show mosquitto >/dev/null 2>&1; then
  $SUDO apt-get update -qq >&2 || true
fi
if ! $SUDO apt-get install -y -qq --no-install-recommends mosquitto mosquitto-clients >&2; then
  echo "setup-mosquitto: apt-get install mosquitto failed (the MQTT tests will skip)" >&2
fi
exit 0
