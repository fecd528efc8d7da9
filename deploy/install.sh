#!/usr/bin/env bash
# install.sh: install portal-daq as a systemd service on the machine's embedded PC.
#
#   sudo deploy/install.sh                 # install into /, enable the service
#   deploy/install.sh --root /tmp/target   # install into another root (image builds, tests)
#
# What it does, all below --root (default /):
#   /opt/portal-daq/venv                 a venv with portal-daq and its dependencies
#   /opt/portal-daq/README.md            the documentation the unit points to
#   /etc/portal-daq/portal-daq.toml      the configuration (kept if it exists)
#   /etc/portal-daq/zenoh.json5          the Zenoh session configuration (kept if it exists)
#   /etc/systemd/system/portal-daq.service
#   /etc/systemd/network/80-can0.network (can0 at 500 kbit/s, bus-off restart)
#   /etc/sysctl.d/90-portal-daq.conf     net.core.rmem_max for the CAN receive buffer
#   /usr/lib/sysusers.d/portal-daq.conf  and the system user portal-daq (systemd-sysusers)
#   the unit enabled (systemctl --root); started only when installing into / with --start.
#
# Options: --root DIR, --start, --with-vcan (also install the bench-testing vcan0 netdev),
#          --pip-args "ARGS" (extra arguments for pip install, e.g. --no-deps).
set -euo pipefail
SOURCE=$(cd "$(dirname "$0")/.." && pwd)
ROOT=/
START=no
VCAN=no
PIP_ARGS=""
while [ $# -gt 0 ]; do
    case "$1" in
        --root) ROOT=$2; shift 2 ;;
        --start) START=yes; shift ;;
        --with-vcan) VCAN=yes; shift ;;
        --pip-args) PIP_ARGS=$2; shift 2 ;;
        -h|--help) sed -n '2,22p' "$0"; exit 0 ;;
        *) echo "install.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
ROOT=$(realpath -m "$ROOT")
at() { echo "${ROOT%/}$1"; }
say() { echo "install.sh: $*"; }

command -v python3 >/dev/null || { echo "install.sh: python3 is needed" >&2; exit 1; }

say "venv in $(at /opt/portal-daq/venv)"
mkdir -p "$(at /opt/portal-daq)"
python3 -m venv "$(at /opt/portal-daq/venv)"
# shellcheck disable=SC2086 # PIP_ARGS is a list of arguments
"$(at /opt/portal-daq/venv/bin/python)" -m pip install -q $PIP_ARGS "$SOURCE"
install -m 0644 "$SOURCE/README.md" "$(at /opt/portal-daq/README.md)"

say "configuration in $(at /etc/portal-daq)"
install -d -m 0755 "$(at /etc/portal-daq)"
for pair in "portal-daq.example.toml:portal-daq.toml" "zenoh.json5:zenoh.json5"; do
    src=${pair%%:*} dst=$(at "/etc/portal-daq/${pair##*:}")
    if [ -e "$dst" ]; then say "keeping existing $dst"; else install -m 0644 "$SOURCE/deploy/$src" "$dst"; fi
done

say "systemd units"
install -D -m 0644 "$SOURCE/deploy/systemd/portal-daq.service" "$(at /etc/systemd/system/portal-daq.service)"
install -D -m 0644 "$SOURCE/deploy/network/80-can0.network" "$(at /etc/systemd/network/80-can0.network)"
if [ "$VCAN" = yes ]; then
    install -m 0644 "$SOURCE/deploy/network/80-vcan0.netdev" "$SOURCE/deploy/network/80-vcan0.network" \
        "$(at /etc/systemd/network/)"
fi
install -D -m 0644 "$SOURCE/deploy/systemd/portal-daq.sysusers" "$(at /usr/lib/sysusers.d/portal-daq.conf)"
install -D -m 0644 "$SOURCE/deploy/sysctl/90-portal-daq.conf" "$(at /etc/sysctl.d/90-portal-daq.conf)"

if [ "$ROOT" = / ]; then
    systemd-sysusers /usr/lib/sysusers.d/portal-daq.conf
    sysctl -q -p /etc/sysctl.d/90-portal-daq.conf
    systemctl daemon-reload
    systemctl enable portal-daq.service
    [ "$START" = yes ] && systemctl restart systemd-networkd portal-daq.service
else
    install -d -m 0755 "$(at /etc)"
    systemd-sysusers --root="$ROOT" "$(at /usr/lib/sysusers.d/portal-daq.conf)"
    systemctl --root="$ROOT" enable portal-daq.service
fi
say "done; check with: systemctl status portal-daq (journalctl -u portal-daq for its log)"
