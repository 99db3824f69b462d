#!/usr/bin/env bash
# Install (or update) posed as a systemd service on a NUC running Debian 12 / Ubuntu 22.04+.
# Run as root from a checkout of the project:   sudo deploy/install.sh [--no-start] [--from PATH]
#
# Idempotent: re-running updates the code and the unit, keeps /etc/posed/config.yaml, the models, the
# events and the history. What it does (deploy/README.md explains each step):
#   Debian packages -> user 'posed' (groups video, plugdev) -> a root-owned copy of the code in /opt/posed/src,
#   built into a wheel installed in the venv /opt/posed/venv -> /etc/posed/config.yaml (only if absent)
#   -> models fetched into /var/lib/posed/models -> the config checked as the service's user, with its folders
#   -> `posed warmup` fills the numba cache /var/cache/posed/numba
#   -> udev rules for RealSense -> unit verified, enabled, started.
set -euo pipefail

PREFIX=${POSED_PREFIX:-/opt/posed}
SYSTEM_PYTHON=${POSED_PYTHON:-/usr/bin/python3}
ETC=/etc/posed
STATE=/var/lib/posed
CACHE=/var/cache/posed
START=1
FROM=()
while [ $# -gt 0 ]; do
    case "$1" in
        --no-start) START=0 ;;
        --from) FROM=(--from "$2"); shift ;;
        -h|--help) sed -n '2,12p' "$0"; exit 0 ;;
        *) echo "install.sh: unknown option $1 (use --no-start, --from PATH)" >&2; exit 2 ;;
    esac
    shift
done

if [ "$(id -u)" -ne 0 ]; then
    echo "install.sh: run as root (sudo deploy/install.sh)" >&2
    exit 1
fi
HERE=$(cd "$(dirname "$0")/.." && pwd)
cd /   # every step runs from /: nothing imports the checkout (its code is copied, owned by root, below)
step() { echo "install.sh: $*"; }

step "Debian packages"
pkgs=(python3 python3-venv python3-dev gcc pkg-config libsystemd-dev libusb-1.0-0 rsync)
missing=()
for p in "${pkgs[@]}"; do dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p"); done
if [ ${#missing[@]} -gt 0 ]; then
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq "${missing[@]}"
fi

step "user posed (groups video, plugdev)"
getent group plugdev >/dev/null || groupadd --system plugdev
getent group video >/dev/null || groupadd --system video
if ! getent passwd posed >/dev/null; then
    useradd --system --user-group --home-dir "$STATE" --no-create-home --shell /usr/sbin/nologin posed
fi
usermod -a -G video,plugdev posed

step "code in $PREFIX/src (root-owned copy), wheel, virtual environment $PREFIX/venv"
# The copy belongs to root and is read-only for everyone else, whoever owns the checkout; the wheel the
# service runs is built from it. Every pip run below reads only that copy: `python -I` (no PYTHON* variables,
# no current folder on sys.path), `pip --isolated` (no PIP_* variables, no user pip.conf), a clean environment
# (but the proxy settings), from /.
install -d -m 0755 -o root -g root "$PREFIX"
rsync -a --delete --chown=root:root --chmod=D0755,F0644 --no-links \
      --exclude .git --exclude .venv --exclude '__pycache__' --exclude '*.egg-info' --exclude build \
      --exclude dist --exclude .pytest_cache --exclude .ruff_cache "$HERE/" "$PREFIX/src/"
chmod 0755 "$PREFIX/src/deploy/"*.sh
# a clean environment keeps only the network proxy settings (downloads from PyPI)
proxies=()
for v in http_proxy https_proxy no_proxy HTTP_PROXY HTTPS_PROXY NO_PROXY; do
    if [ -n "${!v:-}" ]; then proxies+=("$v=${!v}"); fi
done
pip_root() {
    (cd / && env -i PATH=/usr/sbin:/usr/bin:/sbin:/bin HOME=/root LANG=C.UTF-8 "${proxies[@]}" \
        "$PREFIX/venv/bin/python" -I -m pip --isolated --disable-pip-version-check -q "$@")
}
# the system's Python (not a pyenv or conda one in root's home, which the service user cannot run)
[ -x "$PREFIX/venv/bin/python" ] || (cd / && "$SYSTEM_PYTHON" -I -m venv "$PREFIX/venv")
pip_root install --upgrade pip
rm -rf "$PREFIX/wheels"
install -d -m 0755 -o root -g root "$PREFIX/wheels"
pip_root wheel --no-deps -w "$PREFIX/wheels" "$PREFIX/src"
rm -rf "$PREFIX/src/build" "$PREFIX/src/"*.egg-info
wheel=$(ls "$PREFIX"/wheels/posed-*.whl)
pip_root install "$wheel[convert]"                       # the dependencies, and posed if new
pip_root install --no-deps --force-reinstall "$wheel"    # the code of this checkout, same version or not
"$PREFIX/venv/bin/posed" --version

step "configuration $ETC/config.yaml"
install -d -m 0750 -o root -g posed "$ETC"
if [ ! -f "$ETC/config.yaml" ]; then
    "$PREFIX/venv/bin/posed" config template > "$ETC/config.yaml.new"
    chown root:posed "$ETC/config.yaml.new"
    chmod 0640 "$ETC/config.yaml.new"
    mv "$ETC/config.yaml.new" "$ETC/config.yaml"
    step "  wrote the default config; set source (camera) and robot_id there"
fi

step "models in $STATE/models, numba cache in $CACHE/numba"
install -d -m 0750 -o posed -g posed "$STATE" "$STATE/models"
install -d -m 0750 -o posed -g posed "$CACHE" "$CACHE/numba"
runuser -u posed -- env -i PATH=/usr/bin:/bin HOME="$STATE" POSED_MODELS_DIR="$STATE/models" "${proxies[@]}" \
    "$PREFIX/venv/bin/posed" models fetch --models-dir "$STATE/models" "${FROM[@]}"

step "configuration checked as the service will read it"
# as the service's user, with the folders and variables the unit gives it (deploy/posed.service): the models
# folder, the state and cache directories are the service's, not root's, and the user must be able to read
# the file; a bad config stops the install here with every problem listed
runuser -u posed -- env -i PATH=/usr/bin:/bin HOME="$STATE" POSED_MODELS_DIR="$STATE/models" \
    STATE_DIRECTORY="$STATE:$STATE/models" CACHE_DIRECTORY="$CACHE:$CACHE/numba" NUMBA_CACHE_DIR="$CACHE/numba" \
    CONFIGURATION_DIRECTORY="$ETC" "$PREFIX/venv/bin/posed" config check "$ETC/config.yaml"
# the kernels compiled once, as the service's user, into the cache the unit names (NUMBA_CACHE_DIR): the first
# start then loads them (deploy/README.md, docs/benchmarks.md "cold start")
runuser -u posed -- env -i PATH=/usr/bin:/bin HOME="$STATE" NUMBA_CACHE_DIR="$CACHE/numba" \
    POSED_CONFIG="$ETC/config.yaml" "$PREFIX/venv/bin/posed" warmup \
    || step "  (numba warm-up failed: the daemon compiles on its first start, ~30 s before READY)"

step "udev rules for RealSense"
install -m 0644 "$PREFIX/src/deploy/udev/99-posed-realsense.rules" /etc/udev/rules.d/99-posed-realsense.rules
if command -v udevadm >/dev/null; then
    udevadm control --reload-rules || true
    udevadm trigger --subsystem-match=usb --subsystem-match=video4linux --subsystem-match=hidraw || true
fi

step "systemd unit"
unit=/etc/systemd/system/posed.service
sed "s#/opt/posed#$PREFIX#g" "$PREFIX/src/deploy/posed.service" > "$unit.new"
chmod 0644 "$unit.new"
mv "$unit.new" "$unit"
systemd-analyze verify "$unit"
systemctl daemon-reload
systemctl enable posed.service
if [ "$START" = 1 ]; then
    systemctl restart posed.service
    step "started: systemctl status posed; journalctl -u posed -f; $PREFIX/venv/bin/posed watch"
else
    step "enabled, not started (--no-start): systemctl start posed"
fi
