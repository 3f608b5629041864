# Sourced by the setup-*.sh scripts that install a Debian package (Mosquitto, NATS,
# Chromium, tmux): one way to get root, refresh the lists and install, idempotently.
#
#   apt_install TOOL SKIPS PKG...
#
# TOOL names the calling script in messages; SKIPS says what goes untested without the
# package ("the MQTT tests will skip"). Installs PKG... with apt-get (through `sudo -n` when
# not root); refreshes the package lists only when the first package is unknown (a fresh
# container). Returns 0 when installed, else 1 having said why on stderr. Starts nothing.
apt_install() {
  local tool=$1 skips=$2
  shift 2
  local sudo=""
  if [ "$(id -u)" != 0 ]; then
    if command -v sudo >/dev/null 2>&1; then sudo="sudo -n"; else
      echo "$tool: not root and no sudo: cannot install $* ($skips)" >&2
      return 1
    fi
  fi
  export DEBIAN_FRONTEND=noninteractive
  if ! apt-cache show "$1" >/dev/null 2>&1; then
    $sudo apt-get update -qq >&2 || true
  fi
  if ! $sudo apt-get install -y -qq --no-install-recommends "$@" >&2; then
    echo "$tool: apt-get install $* failed ($skips)" >&2
    return 1
  fi
}
