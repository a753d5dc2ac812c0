#!/usr/bin/env bash
# Installs the independent implementations the interoperability tests compare Motus
# against (specs/oracles.md): python-can and canopen (pinned, from PyPI), tshark, and
# LinuxCNC's standalone G-code interpreter rs274 (Debian's linuxcnc-uspace), and headless
# Chromium with Playwright for the HMI's browser tests.
# Idempotent: does nothing when they are already there.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! python3 -c 'import can, canopen' 2>/dev/null; then
  echo "installing python-can and canopen (tests/python/requirements.txt)"
  python3 -m pip install --quiet --disable-pip-version-check -r tests/python/requirements.txt
fi
if ! command -v tshark >/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    echo "installing tshark"
    echo "wireshark-common wireshark-common/install-setuid boolean false" | debconf-set-selections
    DEBIAN_FRONTEND=noninteractive apt-get install -y -q tshark >/dev/null || {
      apt-get update -q >/dev/null && DEBIAN_FRONTEND=noninteractive apt-get install -y -q tshark >/dev/null; }
  else
    echo "tshark is needed by the tests: sudo apt-get install tshark" >&2
    exit 1
  fi
fi
apt_install() {
  DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "$@" >/dev/null || {
    apt-get update -q >/dev/null &&
      DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "$@" >/dev/null; }
}
if ! command -v rs274 >/dev/null || ! /usr/bin/python3 -c 'import gcode' 2>/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    echo "installing linuxcnc-uspace (rs274 and its Python gcode module)"
    apt_install linuxcnc-uspace
  else
    echo "rs274 is needed by the tests: sudo apt-get install --no-install-recommends linuxcnc-uspace" >&2
    exit 1
  fi
fi
if ! command -v curl >/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    echo "installing curl (the README's station block asks the API with it)"
    apt_install curl ca-certificates
  else
    echo "curl is needed by the README test: sudo apt-get install curl" >&2
    exit 1
  fi
fi
if ! command -v chromium >/dev/null; then
  if [ "$(id -u)" = 0 ]; then
    echo "installing chromium (browser tests of the web HMI)"
    apt_install chromium
  else
    echo "chromium is needed by the browser tests: sudo apt-get install --no-install-recommends chromium" >&2
    exit 1
  fi
fi
if ! python3 -c 'import playwright' 2>/dev/null; then
  echo "installing playwright (tests/browser/requirements.txt; drives Debian's chromium)"
  python3 -m pip install --quiet --disable-pip-version-check -r tests/browser/requirements.txt
fi
