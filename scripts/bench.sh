#!/usr/bin/env bash
# Every benchmark in one command: the engine's per-scan Google Benchmark, then bgkmapd under
# end-to-end load over loopback. Results go to stdout and out/bench/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target scan_update_benchmark server_load bgkmapd
mkdir -p out/bench
build/bench/scan_update_benchmark --benchmark_counters_tabular=true --benchmark_min_time=2 \
  | tee out/bench/scan_update.txt

ADDR="127.0.0.1:${BGKMAP_BENCH_PORT:-50571}"
build/server/bgkmapd --listen "$ADDR" >out/bench/bgkmapd.log 2>&1 &
SERVER=$!
trap 'kill -TERM $SERVER 2>/dev/null || true; wait $SERVER 2>/dev/null || true' EXIT
build/bench/server_load --server "$ADDR" | tee out/bench/server_load.md
