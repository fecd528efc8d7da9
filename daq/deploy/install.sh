#!/usr/bin/env bash
# install.sh: install portal-daq as a systemd service on the machine's embedded PC.
#
#   sudo deploy/install.sh                 # from a clone: install its source tree into /
#   deploy/install.sh --root /tmp/target   # install into another root (tests); the venv's
#                                          # scripts name /tmp/target/opt/...: for a machine
#                                          # image, run install.sh inside its chroot
#   sudo ./install.sh --package portal_daq-0.1.0-py3-none-any.whl
#                                          # from `portal-daq init DIR --deploy` (a wheel's)
#
# What it does, all below --root (default /):
#   /opt/portal-daq/venv                 a venv with portal-daq and its dependencies
#   /opt/portal-daq/README.md            the documentation the unit points to
#   /etc/portal-daq/portal-daq.toml      the configuration (kept if it exists): the one
#                                        beside the kit (init --deploy's DIR), else the
#                                        package's example
#   /etc/portal-daq/zenoh.json5          the Zenoh session configuration (the same)
#   /etc/portal-daq/*.dbc                the DBCs beside it (the example's: a copy of the
#                                        packaged DBC, which it reads until told otherwise)
#   /etc/systemd/system/portal-daq.service  bound to the configuration's [bus] channel
#   /etc/systemd/network/80-can0.network (can0 at 500 kbit/s, bus-off restart; named
#                                        and matching the [bus] channel; none for a vcan)
#   /etc/sysctl.d/90-portal-daq.conf     net.core.rmem_max for the CAN receive buffer
#   /usr/lib/sysusers.d/portal-daq.conf  and the system user portal-daq (systemd-sysusers)
#   the unit enabled (systemctl --root); started only when installing into / with --start.
#
# Options: --root DIR, --start, --with-vcan (also install the bench-testing vcan0 netdev),
#          --package SPEC (what pip installs: a wheel file, or any pip requirement; default:
#          the source tree this script sits in, deploy/ of a clone),
#          --pip-args "ARGS" (extra arguments for pip install, e.g. --no-deps).
set -euo pipefail
KIT=$(cd "$(dirname "$0")" && pwd)
ROOT=/
START=no
VCAN=no
PIP_ARGS=""
PACKAGE=""
while [ $# -gt 0 ]; do
    case "$1" in
        --root) ROOT=$2; shift 2 ;;
        --start) START=yes; shift ;;
        --with-vcan) VCAN=yes; shift ;;
        --package) PACKAGE=$2; shift 2 ;;
        --pip-args) PIP_ARGS=$2; shift 2 ;;
        -h|--help) sed -n '2,/^set -euo/p' "$0" | sed '$d'; exit 0 ;;
        *) echo "install.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    esac
done
if [ -z "$PACKAGE" ]; then
    if [ -f "$KIT/../pyproject.toml" ]; then
        PACKAGE=$(cd "$KIT/.." && pwd)
    else
        echo "install.sh: no source tree around $KIT: give --package, the portal-daq wheel" \
            "to install (e.g. --package portal_daq-0.1.0-py3-none-any.whl)" >&2
        exit 2
    fi
fi
ROOT=$(realpath -m "$ROOT")
at() { echo "${ROOT%/}$1"; }
say() { echo "install.sh: $*"; }

command -v python3 >/dev/null || { echo "install.sh: python3 is needed" >&2; exit 1; }

VENV=$(at /opt/portal-daq/venv)
say "venv in $VENV"
mkdir -p "$(at /opt/portal-daq)"
python3 -m venv "$VENV"
# shellcheck disable=SC2086 # PIP_ARGS is a list of arguments
"$VENV/bin/python" -m pip install -q $PIP_ARGS "$PACKAGE"
# The README is the package's description: the same text a clone has.
"$VENV/bin/python" -c 'import importlib.metadata as m, sys
sys.stdout.write(m.metadata("portal-daq").get_payload())' > "$(at /opt/portal-daq/README.md)"

# The configuration: the one beside the kit (`portal-daq init DIR --deploy` wrote it into
# DIR, edited since, maybe with a DBC of the machine's), else the package's example.
if [ -f "$KIT/../portal-daq.toml" ]; then
    config=$(cd "$KIT/.." && pwd)
else
    config=$(mktemp -d)
    trap 'rm -rf "$config"' EXIT
    if ! made=$("$VENV/bin/portal-daq" init "$config" 2>&1); then echo "$made" >&2; exit 1; fi
fi
say "configuration in $(at /etc/portal-daq) from $config"
install -d -m 0755 "$(at /etc/portal-daq)"
for src in "$config"/portal-daq.toml "$config"/zenoh.json5 "$config"/*.dbc; do
    [ -e "$src" ] || continue
    dst=$(at "/etc/portal-daq/${src##*/}")
    if [ -e "$dst" ]; then say "keeping existing $dst"; else install -m 0644 "$src" "$dst"; fi
done

# The unit waits for, and is bound to, the CAN interface the installed configuration reads
# ([bus] channel); the kit's files name can0. Bound to can0, a machine whose sensors are on
# can1, or a bench on vcan0, never started the service (its start waited for can0).
bus=$("$VENV/bin/python" - "$(at /etc/portal-daq/portal-daq.toml)" <<'PY'
import sys, tomllib
try:
    with open(sys.argv[1], "rb") as file:
        bus = tomllib.load(file).get("bus", {})
except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as error:
    sys.exit(f"install.sh: {sys.argv[1]}: {error}; fix it and run install.sh again")
values = bus if isinstance(bus, dict) else {}
interface, channel = values.get("interface", "socketcan"), values.get("channel", "can0")
if values is not bus or not all(isinstance(v, str) and v.strip() for v in (interface, channel)):
    sys.exit(
        f"install.sh: {sys.argv[1]}: [bus] must be a table whose interface and channel are "
        "names (interface = \"socketcan\", channel = \"can0\"); fix it and run install.sh again"
    )
print(interface, channel)
PY
)
read -r interface channel <<<"$bus"
say "systemd units for [bus] interface $interface, channel $channel"
unit=$(<"$KIT/systemd/portal-daq.service")
can0=sys-subsystem-net-devices-can0.device
if [ "$interface" = socketcan ]; then
    device=$(systemd-escape --path --suffix=device "/sys/subsystem/net/devices/$channel")
    unit=${unit//"$can0"/"$device"}
else  # no network interface to wait for (a python-can interface of its own)
    unit=$(grep -v "^BindsTo=$can0\$" <<<"$unit")
    unit=${unit//" $can0"/}
    unit=${unit//"After=$can0 "/After=}
fi
install -d -m 0755 "$(at /etc/systemd/system)"
printf '%s\n' "$unit" > "$(at /etc/systemd/system/portal-daq.service)"
chmod 0644 "$(at /etc/systemd/system/portal-daq.service)"
install -d -m 0755 "$(at /etc/systemd/network)"
networks=""  # what only systemd-networkd brings up
if [ "$interface" = socketcan ] && [ "${channel#vcan}" = "$channel" ]; then
    network=$(<"$KIT/network/80-can0.network")
    printf '%s\n' "${network//Name=can0/"Name=$channel"}" > "$(at "/etc/systemd/network/80-$channel.network")"
    networks="80-$channel.network"
fi
if [ "$VCAN" = yes ]; then
    install -m 0644 "$KIT/network/80-vcan0.netdev" "$KIT/network/80-vcan0.network" \
        "$(at /etc/systemd/network/)"
    networks="${networks:+$networks }80-vcan0.netdev"
fi
install -D -m 0644 "$KIT/systemd/portal-daq.sysusers" "$(at /usr/lib/sysusers.d/portal-daq.conf)"
install -D -m 0644 "$KIT/sysctl/90-portal-daq.conf" "$(at /etc/sysctl.d/90-portal-daq.conf)"

if [ "$ROOT" = / ]; then
    systemd-sysusers /usr/lib/sysusers.d/portal-daq.conf
    sysctl -q -p /etc/sysctl.d/90-portal-daq.conf
    systemctl daemon-reload
    systemctl reenable portal-daq.service
    [ "$START" = yes ] && systemctl restart systemd-networkd portal-daq.service
else
    install -d -m 0755 "$(at /etc)"
    systemd-sysusers --root="$ROOT" "$(at /usr/lib/sysusers.d/portal-daq.conf)"
    systemctl --root="$ROOT" reenable portal-daq.service
fi
# Debian's network is ifupdown's unless told otherwise: networkd, disabled, reads no file
# of ours, and the CAN link stays down after a reboot (the service says "bus down").
# Not enabled here: with it comes systemd-networkd-wait-online, which on a PC whose other
# links networkd does not manage can hold network-online.target (and this unit) for 2 min.
if [ -n "$networks" ]; then
    if [ "$ROOT" = / ]; then
        networkd=$(systemctl is-enabled systemd-networkd.service 2>/dev/null || true)
    else
        networkd=$(systemctl --root="$ROOT" is-enabled systemd-networkd.service 2>/dev/null || true)
    fi
    case "$networkd" in
        enabled|enabled-runtime|static|indirect|alias) ;;
        *) say "warning: systemd-networkd is ${networkd:-not installed} here: nothing reads" \
               "$networks at boot, and $channel is not brought up after a reboot; enable it" \
               "(systemctl enable systemd-networkd; if the boot then waits for" \
               "network-online, systemctl disable systemd-networkd-wait-online), or bring" \
               "$channel up as this PC's network is set up (ifupdown: a 'can' stanza in" \
               "/etc/network/interfaces.d/ with the bitrate of $networks)" ;;
    esac
fi
say "done; check with: systemctl status portal-daq (journalctl -u portal-daq for its log)"
