#!/usr/bin/env bash
# demo.sh: the main job on a bench: the simulator bridge plays one movement cycle onto a
# real SocketCAN vcan0, the DAQ service decodes it, estimates the soil pressures, publishes
# them on Zenoh and records MCAP, and the monitor prints what a dashboard receives.
# At the end a report of the recording (with the simulation truth) is written.
#
#   deploy/demo.sh [SPEED]     (./dev demo does this; SPEED defaults to 0.5)
#
# Where the host has no vcan0 (no CAN support in its kernel), the whole demo runs inside
# User-Mode Linux through tests/vcan/with-vcan. There one CPU and ~0.1 ms per system call
# leave room for about 600 frames/s through service, bridge and monitor together, so the
# cycle plays at half speed by default (the DBC's traffic is ~1,010 frames/s); on a Linux
# host with vcan0 or on the machine, `deploy/demo.sh 1` plays it in real time.
# Output files go to a fresh /tmp directory.
set -euo pipefail
cd "$(dirname "$0")/.."
SPEED=${1:-0.5}
PY=${PYTHON:-$PWD/.venv/bin/python}
if [ ! -e /sys/class/net/vcan0 ]; then
    exec tests/vcan/with-vcan env PYTHON="$PY" "$0" "$SPEED"
fi

work=$(mktemp -d /tmp/portal-daq-demo.XXXXXX)
cp deploy/zenoh.json5 "$work/zenoh.json5"
# Slow motion stretches the cycle times: scale the staleness limit with it.
stale=$(awk -v s="$SPEED" 'BEGIN { printf "%.2f", (s < 1 ? 3 / s : 3) }')
# Truth is recorded; the bridge publishes it through a Unix socket, the only link
# zenoh.json5's access control accepts puts under portal/** from.
socket="unixsock-stream/$work/zenoh.sock"
sed -e 's/^channel = "can0"/channel = "vcan0"/' \
    -e 's#^directory = .*#directory = "recordings"#' \
    -e 's/^truth = false/truth = true/' \
    -e "s|^# listen = .*|listen = [\"tcp/127.0.0.1:7447\", \"$socket\"]|" \
    -e "s/^stale_after_cycles = .*/stale_after_cycles = $stale/" \
    deploy/portal-daq.example.toml > "$work/portal-daq.toml"
endpoint=tcp/127.0.0.1:7447
cycle_s=$(awk -v s="$SPEED" 'BEGIN { printf "%d", 45 / s + 6 }')

echo "demo: service on vcan0, simulator at ${SPEED}x, monitor for ${cycle_s} s; files in $work"
"$PY" -m daq run --config "$work/portal-daq.toml" --log-level WARNING &
service=$!
trap 'kill $service 2>/dev/null || true' EXIT
"$PY" -m daq monitor --config "$work/portal-daq.toml" --connect "$endpoint" --plain \
    --duration "$cycle_s" &
monitor=$!
"$PY" -m sim_bridge --config deploy/machine.example.toml --channel vcan0 --speed "$SPEED" \
    --cycles 1 --zenoh --mode peer --connect "$socket" --listen tcp/127.0.0.1:0 \
    --no-multicast-scouting \
    --truth-csv "$work/truth.csv" -q
wait "$monitor" || true
kill -TERM "$service" && wait "$service" || true
trap - EXIT

recording=$(ls "$work"/recordings/*.mcap | head -n 1)
"$PY" -m daq report "$recording" --out "$work/report" >/dev/null
echo "demo: recording $recording"
echo "demo: report    $work/report/report.html"
echo "demo: truth     $work/truth.csv"
