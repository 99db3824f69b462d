#!/usr/bin/env bash
# Install (or update) posed as a systemd service on a NUC running Debian 12 / Ubuntu 22.04+.
# Run as root from a checkout of the project:   sudo deploy/install.sh [--no-start] [--from PATH]
#
# Idempotent: re-running updates the code and the unit, keeps /etc/posed/config.yaml, the models, the
# events and the history. What it does (deploy/README.md explains each step):
#   Debian packages -> user 'posed' (groups video, plugdev) -> code in /opt/posed/src, venv /opt/posed/venv
#   -> /etc/posed/config.yaml (only if absent) checked -> models fetched into /var/lib/posed/models
#   -> numba cache warmed in /var/cache/posed/numba -> udev rules for RealSense -> unit verified, enabled, started.
set -euo pipefail

PREFIX=${POSED_PREFIX:-/opt/posed}
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

step "code in $PREFIX/src, virtual environment $PREFIX/venv"
install -d -m 0755 "$PREFIX"
rsync -a --delete --exclude .git --exclude .venv --exclude '__pycache__' --exclude '*.egg-info' \
      --exclude .pytest_cache --exclude .ruff_cache "$HERE/" "$PREFIX/src/"
[ -x "$PREFIX/venv/bin/python" ] || python3 -m venv "$PREFIX/venv"
"$PREFIX/venv/bin/python" -m pip install -q --upgrade pip
# editable: the embedded config.yaml and docs stay next to the code (read-only for the service)
"$PREFIX/venv/bin/python" -m pip install -q -e "$PREFIX/src[convert]"
"$PREFIX/venv/bin/python" -m compileall -q "$PREFIX/src" >/dev/null || true

step "configuration $ETC/config.yaml"
install -d -m 0750 -o root -g posed "$ETC"
if [ ! -f "$ETC/config.yaml" ]; then
    install -m 0640 -o root -g posed "$PREFIX/src/config.yaml" "$ETC/config.yaml"
    step "  wrote the default config; set source (camera) and robot_id there"
fi
"$PREFIX/venv/bin/posed" config check "$ETC/config.yaml"

step "models in $STATE/models, numba cache in $CACHE/numba"
install -d -m 0750 -o posed -g posed "$STATE" "$STATE/models"
install -d -m 0750 -o posed -g posed "$CACHE" "$CACHE/numba"
runuser -u posed -- env HOME="$STATE" POSED_MODELS_DIR="$STATE/models" \
    "$PREFIX/venv/bin/posed" models fetch --models-dir "$STATE/models" "${FROM[@]}"
runuser -u posed -- env HOME="$STATE" NUMBA_CACHE_DIR="$CACHE/numba" "$PREFIX/venv/bin/python" -c \
    "from daemon.config import load_config; from fitting.fitter import Fitter; Fitter(load_config('$ETC/config.yaml').fitting).warmup()" \
    || step "  (numba warm-up skipped: the daemon compiles on its first start)"

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
