#!/usr/bin/env bash
# CPU milliseconds per scan of an ingest (docs/benchmarks.md, "Ingest rate"): each real sequence
# streamed by `bgkmap insert`, --float32 then compact (the default), to a fresh in-memory bgkmapd;
# the client's user + sys time (the whole process) and the server's utime + stime over the insert,
# with the wall rate. What the two cores pay per scan, whatever else loads the machine. Given
# several build dirs (e.g. main's and a branch's) it alternates them, ROUNDS times.
#   scripts/bench-ingest-cpu.sh [ROUNDS] BUILD_DIR...
set -euo pipefail
cd "$(dirname "$0")/.."
ROUNDS="${1:-3}"
shift || true
BUILDS=("${@:-build}")
DATA="${BGKMAP_SHARED_DATA:-../shared/data}"
PORT="${BGKMAP_BENCH_PORT:-57411}"
OUT="$(mktemp -d)"
SERVER=""
trap '[ -n "$SERVER" ] && kill -KILL "$SERVER" 2>/dev/null; rm -rf "$OUT"' EXIT
TCK=$(getconf CLK_TCK)
cpu_ms() { awk -v t="$TCK" '{print ($14 + $15) * 1000 / t}' "/proc/$1/stat"; }
for round in $(seq "$ROUNDS"); do
  for build in "${BUILDS[@]}"; do
    PORT=$((PORT + 1))
    "$build/server/bgkmapd" --listen "127.0.0.1:$PORT" --log-level warn >"$OUT/server.log" 2>&1 &
    SERVER=$!
    for _ in $(seq 100); do (echo >"/dev/tcp/127.0.0.1/$PORT") 2>/dev/null && break; sleep 0.1; done
    echo "== $build, round $round, $(uptime)"
    for seq in ouster_os1_128_street kitti_raw_0048 balm_hall; do
      n=$(ls "$DATA/$seq/velodyne" | wc -l)
      for mode in --float32 ""; do
        s0=$(cpu_ms "$SERVER")
        /usr/bin/time -o "$OUT/time" -f "%U %S %e" "$build/tools/bgkmap/bgkmap" insert \
          --server "127.0.0.1:$PORT" --robot "$seq$mode" "$DATA/$seq" $mode >/dev/null 2>&1
        s1=$(cpu_ms "$SERVER")
        read -r user sys wall <"$OUT/time"
        awk -v s="$seq" -v m="${mode:-compact}" -v n="$n" -v u="$user" -v y="$sys" -v w="$wall" \
          -v a="$s0" -v b="$s1" 'BEGIN {printf "%s %s: client %.1f ms/scan, server %.1f ms/scan, %.1f scans/s\n",
          s, m, (u + y) * 1000 / n, (b - a) / n, n / w}'
      done
    done
    kill -INT "$SERVER"
    wait "$SERVER" || true
    SERVER=""
  done
done
