#!/usr/bin/env bash
# Every benchmark in one command: the engine's per-scan Google Benchmark, then bgkmapd under
# end-to-end load over loopback. Results go to stdout and out/bench/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build  # the configuration of scripts/test.sh and demo.sh
cmake --build build -j"$(nproc)" --target scan_update_benchmark server_load bgkmapd
mkdir -p out/bench
build/bench/scan_update_benchmark --benchmark_counters_tabular=true --benchmark_min_time=2 \
  | tee out/bench/scan_update.txt
# One dense real scan in two bands on two threads against whole (docs/benchmarks.md, "A scan in
# bands on the server").
cmake --build build -j"$(nproc)" --target scan_bands
build/bench/scan_bands "${BGKMAP_SHARED_DATA:-../shared/data}/kitti_raw_0048" \
  --config experiments/robots/car_kitti.yaml --bands 2 --rounds 5 | tee out/bench/scan_bands.txt

ADDR="127.0.0.1:${BGKMAP_BENCH_PORT:-50571}"
build/server/bgkmapd --listen "$ADDR" >out/bench/bgkmapd.log 2>&1 &
SERVER=$!
trap 'kill -TERM $SERVER 2>/dev/null || true; wait $SERVER 2>/dev/null || true' EXIT
build/bench/server_load --server "$ADDR" | tee out/bench/server_load.md
kill -TERM $SERVER && wait $SERVER || true

# Storage at scale (docs/benchmarks.md, "Bounded memory and lazy restart"): bgkmapd restarted on
# a store of 10^8 known cells (built once, ~1.8 GB in out/bench/store_1e8), and a map of 40 and
# 80 places under storage.max_memory_mb = 64 against the same run unbounded.
cmake --build build -j"$(nproc)" --target store_scale
build/bench/store_scale --bgkmapd build/server/bgkmapd restart --data-dir out/bench/store_1e8 \
  | tee out/bench/store_restart.md
build/bench/store_scale --bgkmapd build/server/bgkmapd bounded --sites 40 --bound-mb 64 \
  | tee out/bench/store_bounded.md
build/bench/store_scale --bgkmapd build/server/bgkmapd bounded --sites 80 --bound-mb 64 0 \
  | tail -n 2 | tee -a out/bench/store_bounded.md

# Pose corrections (docs/benchmarks.md, "Pose corrections"): a 1,000-scan drive on drifting
# odometry, 10 % corrected, against its full ingest; another robot's load during a correction.
cmake --build build -j"$(nproc)" --target correction_load
CDIR=$(mktemp -d)
CADDR="127.0.0.1:${BGKMAP_BENCH_CORRECTION_PORT:-50572}"
build/server/bgkmapd --listen "$CADDR" --data-dir "$CDIR/map" --set storage.durability=periodic \
  >out/bench/bgkmapd_correction.log 2>&1 &
CSERVER=$!
trap 'kill -TERM $CSERVER 2>/dev/null || true; wait $CSERVER 2>/dev/null || true; rm -rf "$CDIR"' EXIT
build/bench/correction_load --server "$CADDR" | tee out/bench/correction.md
kill -TERM $CSERVER && wait $CSERVER || true
