#!/usr/bin/env bash
# Memory per known cell of a served map (docs/benchmarks.md, "Memory per known cell", issue 28):
# a fresh in-memory bgkmapd with a robot's settings (experiments/robots/) takes one real sequence
# streamed by `bgkmap insert`; then the growth of its resident set (/proc/PID/status VmRSS, from
# just before the insert to after it, once packing has settled, and once idle: the workers'
# engine scratch handed back) and its tile memory (GET
# /metrics, bgkmap_map_tile_memory_bytes) divided by the known cells (bgkmap_map_known_cells),
# with the insert's wall rate. Each set runs with storage.dense_tiles_mb = 0 (every tile dense)
# and with each DENSE_MB given, ROUNDS times alternating, on the same binary.
#   scripts/bench-memory.sh [BUILD_DIR=build] [ROUNDS=1] [DENSE_MB...=64]
# METHOD=bgk-ll runs the local-linear method instead of the robots' bgk+; SETS picks sequences
# (default "kitti_raw_0048:car_kitti ouster_os1_128_street:car_ouster balm_hall:handheld_hall").
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
ROUNDS="${2:-1}"
shift 2 || shift $# || true
BUDGETS=("${@:-64}")
DATA="${BGKMAP_SHARED_DATA:-../shared/data}"
PORT="${BGKMAP_BENCH_PORT:-57511}"
METHOD="${METHOD:-bgk+}"
OUT="$(mktemp -d)"
SERVER=""
trap '[ -n "$SERVER" ] && kill -KILL "$SERVER" 2>/dev/null; rm -rf "$OUT"' EXIT
source scripts/memory-bench-lib.sh
hwm_kb() { awk '/^VmHWM:/ {print $2}' "/proc/$1/status"; }
metric() { curl -s "http://127.0.0.1:$HTTP/metrics" | awk -v k="$1" '$1 == k {print $2}'; }
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg); method $METHOD"
SETS="${SETS:-kitti_raw_0048:car_kitti ouster_os1_128_street:car_ouster balm_hall:handheld_hall}"
for set in $SETS; do
  input="$DATA/${set%%:*}"
  config="experiments/robots/${set##*:}.yaml"
  n=$(ls "$input/velodyne" | wc -l)
  for round in $(seq "$ROUNDS"); do
    for mb in 0 "${BUDGETS[@]}"; do
      PORT=$((PORT + 2))
      HTTP=$((PORT + 1))
      "$BUILD/server/bgkmapd" --config "$config" --set "method=$METHOD" \
        --set "storage.dense_tiles_mb=$mb" --listen "127.0.0.1:$PORT" --http "127.0.0.1:$HTTP" \
        --log-level warn >"$OUT/server.log" 2>&1 &
      SERVER=$!
      for _ in $(seq 100); do (echo >"/dev/tcp/127.0.0.1/$HTTP") 2>/dev/null && break; sleep 0.1; done
      r0=$(rss_kb "$SERVER")
      t0=$(date +%s%N)
      "$BUILD/tools/bgkmap/bgkmap" insert --server "127.0.0.1:$PORT" --robot r "$input" \
        >/dev/null 2>&1
      t1=$(date +%s%N)
      # Packing runs on the eviction thread (at the latest every second): wait until the tile
      # memory has not changed for 2 s.
      prev=-1
      same=0
      for _ in $(seq 200); do
        b=$(metric bgkmap_map_tile_memory_bytes)
        if [ "$b" = "$prev" ]; then same=$((same + 1)); else same=0; fi
        [ "$same" -ge 4 ] && break
        prev=$b
        sleep 0.5
      done
      r1=$(rss_kb "$SERVER")
      r2=$(idle_rss_kb "$SERVER" "$t1")
      hwm=$(hwm_kb "$SERVER")
      known=$(metric bgkmap_map_known_cells)
      tiles=$(metric bgkmap_map_tiles)
      packed=$(metric bgkmap_map_packed_tiles)
      awk -v s="${set%%:*}" -v mb="$mb" -v n="$n" -v r0="$r0" -v r1="$r1" -v r2="$r2" -v hwm="$hwm" \
        -v k="$known" -v b="$prev" -v t="$tiles" -v p="$packed" -v w="$(((t1 - t0) / 1000000))" \
        'BEGIN {printf "%s dense_tiles_mb %s: %d known cells, %d tiles (%d packed); RSS +%.1f MB = %.1f B/known cell, idle +%.1f MB = %.1f B/known cell (peak %.1f MB); tiles %.1f MB = %.1f B/known cell; %.1f scans/s\n",
        s, mb, k, t, p, (r1 - r0) / 1024, (r1 - r0) * 1024 / k, (r2 - r0) / 1024, (r2 - r0) * 1024 / k, hwm / 1024, b / 1048576, b / k, n * 1000 / w}'
      kill -INT "$SERVER"
      wait "$SERVER" || true
      SERVER=""
    done
  done
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
