#!/bin/sh
# Install Debian's headless Chromium and its driver for the preview's browser tests.
# Idempotent: does nothing when both /usr/bin/chromium and /usr/bin/chromedriver are there
# (Chromium alone is not enough: selenium drives it through chromedriver). Needs root and apt.
set -eu
CHROMIUM_BIN="${CHROMIUM_BIN:-/usr/bin/chromium}"          # overridable for tests/test_ci.py
CHROMEDRIVER_BIN="${CHROMEDRIVER_BIN:-/usr/bin/chromedriver}"
if [ -x "$CHROMIUM_BIN" ] && [ -x "$CHROMEDRIVER_BIN" ]; then
    exit 0
fi
if [ "$(id -u)" != "0" ]; then
    echo "install_chromium.sh: needs root to apt-get install chromium chromium-driver" >&2
    exit 3
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_chromium.sh: apt-get not found (not a Debian-like system): install Chromium and chromedriver at /usr/bin" >&2
    exit 4
fi
export DEBIAN_FRONTEND=noninteractive
apt-get -o DPkg::Lock::Timeout=900 update -qq
apt-get -o DPkg::Lock::Timeout=900 install -y -qq --no-install-recommends chromium chromium-driver fonts-dejavu-core
test -x "$CHROMIUM_BIN" && test -x "$CHROMEDRIVER_BIN"
