#!/usr/bin/env bash
# The live logger under load: `camera_sim` publishes a 50 s work-zone drive lap after lap at
# 30 fps with 64 3D detections a frame, its GNSS receiver (5 Hz NMEA) and wheel speed (50 Hz
# CCVS1) written to FIFOs; `dash2sim record` subscribes, reads both FIFOs, runs the pipeline
# with the road's map and writes rotating files. Every 10 s the logger's resident memory and
# CPU are sampled from /proc. Figures in docs/benchmarks.md.
#
#   adapters/linux/benches/record_load.sh [MINUTES]     (default 10; each lap is 50 s)
set -euo pipefail
minutes=${1:-10}
laps=$(( (minutes * 60 + 49) / 50 ))
root=$(cd "$(dirname "$0")/../../.." && pwd)
cd "$root"
cargo build --release -q -p dash2sim -p dash2sim-examples --bin dash2sim --bin camera_sim
bin=$root/target/release
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export IOX2_LOG_LEVEL=Error
"$bin/dash2sim" scenario generate --seed 1 --duration 50 -o "$work/drive" > /dev/null
"$bin/dash2sim" map build "$work/drive/road.osm" --origin 60.2711,24.8572 -o "$work/road.d2smap" > /dev/null
mkfifo "$work/gnss.fifo" "$work/can.fifo"
prefix="dash2sim-load/$$"
"$bin/dash2sim" record -o "$work/log" --map "$work/road.d2smap" --camera "$prefix" \
  --serial "$work/gnss.fifo" --can-replay "$work/can.fifo" --segment-minutes 1 --json > "$work/summary.json" &
logger=$!
"$bin/camera_sim" --fps 30 --objects 64 --seconds 50 --laps "$laps" --prefix "$prefix" \
  --nmea-out "$work/gnss.fifo" --can-out "$work/can.fifo" > "$work/camera.txt" &
camera=$!
ticks=$(getconf CLK_TCK)
cpu() { awk '{print $14 + $15}' "/proc/$logger/stat"; }
printf '%8s %12s %10s\n' "t (s)" "RSS (KiB)" "CPU (%)"
last=$(cpu); t=0
while kill -0 "$camera" 2> /dev/null; do
  sleep 10; t=$((t + 10))
  kill -0 "$logger" 2> /dev/null || { echo "the logger died" >&2; exit 1; }
  now=$(cpu)
  rss=$(awk '/^VmRSS/ {print $2}' "/proc/$logger/status")
  awk -v t="$t" -v rss="$rss" -v d="$((now - last))" -v hz="$ticks" 'BEGIN {printf "%8d %12d %10.1f\n", t, rss, 100 * d / hz / 10}'
  last=$now
done
wait "$camera"
hwm=$(awk '/^VmHWM/ {print $2}' "/proc/$logger/status")
kill -TERM "$logger"; wait "$logger"
echo "camera: $(cat "$work/camera.txt"); logger peak RSS (VmHWM) ${hwm} KiB; files: $(ls "$work/log" | wc -l)"
echo "logger: $(cat "$work/summary.json")"
"$bin/dash2sim" inspect "$work/log/$(ls "$work/log" | tail -1)" > "$work/inspect.txt"; head -14 "$work/inspect.txt"
