#!/bin/sh
# Install Debian's headless Chromium (and its driver) for the preview's browser tests.
# Idempotent: does nothing when /usr/bin/chromium is already there. Needs root and apt.
set -eu
if [ -x /usr/bin/chromium ]; then
    exit 0
fi
if [ "$(id -u)" != "0" ]; then
    echo "install_chromium.sh: needs root to apt-get install chromium" >&2
    exit 3
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install_chromium.sh: apt-get not found (not a Debian-like system)" >&2
    exit 4
fi
export DEBIAN_FRONTEND=noninteractive
apt-get -o DPkg::Lock::Timeout=900 update -qq
apt-get -o DPkg::Lock::Timeout=900 install -y -qq --no-install-recommends chromium chromium-driver fonts-dejavu-core
test -x /usr/bin/chromium
