#!/usr/bin/env bash
# Set up a development/test machine from nothing: Debian packages the Python dependencies need,
# a virtual environment, and the project installed editable with its test extras. Idempotent.
set -euo pipefail
PYTHON=${PYTHON:-python3}
VENV=${VENV:-.venv}

need_apt=()
dpkg -s libsystemd-dev >/dev/null 2>&1 || need_apt+=(libsystemd-dev)   # systemd-python builds from source
dpkg -s pkg-config     >/dev/null 2>&1 || need_apt+=(pkg-config)
dpkg -s libusb-1.0-0   >/dev/null 2>&1 || need_apt+=(libusb-1.0-0)     # pyrealsense2 needs it to import
command -v gcc >/dev/null 2>&1          || need_apt+=(gcc)
command -v openssl >/dev/null 2>&1      || need_apt+=(openssl)   # deploy/zenoh/make-certs.sh, tests/daemon/test_bus_security.py
command -v systemd-analyze >/dev/null 2>&1 || need_apt+=(systemd)   # deploy/posed.service is checked by systemd-analyze verify
command -v chromium >/dev/null 2>&1        || need_apt+=(chromium)  # tests/viz: the web view in a real headless browser
if [ ${#need_apt[@]} -gt 0 ]; then
    if [ "$(id -u)" -ne 0 ]; then
        echo "bootstrap: missing Debian packages: ${need_apt[*]}; run: sudo apt-get install ${need_apt[*]}" >&2
        exit 1
    fi
    echo "bootstrap: installing Debian packages: ${need_apt[*]}"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${need_apt[@]}"
fi

if [ ! -x "$VENV/bin/python" ]; then
    "$PYTHON" -m venv "$VENV"
fi
"$VENV/bin/python" -m pip install -q --upgrade pip
"$VENV/bin/python" -m pip install -q -e ".[dev]"
echo "bootstrap: $VENV ready"
