#!/usr/bin/env bash
# A cluster shard's resident set after a real drive and once idle (docs/server.md, "Idle workers
# hand their scratch back"; issue 28): one nats-server with JetStream and one bgkmapd shard on
# loopback (cluster.replicas 1), the sequence streamed by `bgkmap insert` with a robot's settings;
# the shard's VmRSS before the insert, once every scan is applied (bgkmap_map_version), and idle
# (its log reader hands the engine's scratch back after two quiet seconds, QuietScratch;
# idle_rss_kb in memory-bench-lib.sh), with the known cells. ROUNDS runs.
#   scripts/bench-memory-cluster.sh [BUILD_DIR=build] [ROUNDS=1] [SET=kitti_raw_0048:car_kitti]
# Needs nats-server (scripts/install-deps.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
ROUNDS="${2:-1}"
SET="${3:-kitti_raw_0048:car_kitti}"
DATA="${BGKMAP_SHARED_DATA:-../shared/data}"
PORT="${BGKMAP_BENCH_PORT:-57811}"
input="$DATA/${SET%%:*}"
config="experiments/robots/${SET##*:}.yaml"
n=$(ls "$input/velodyne" | wc -l)
OUT="$(mktemp -d)"
PIDS=()
trap 'for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done; rm -rf "$OUT"' EXIT
source scripts/memory-bench-lib.sh
metric() { curl -s "http://127.0.0.1:$HTTP/metrics" | awk -v k="$1" '$1 == k {print $2}'; }
taken() { (echo >"/dev/tcp/127.0.0.1/$1") 2>/dev/null; }
(umask 077 && openssl rand -hex 32 >"$OUT/cluster.key")
for round in $(seq "$ROUNDS"); do
  NATS_PORT=$((PORT + 3 * round)); LISTEN=$((NATS_PORT + 1)); HTTP=$((NATS_PORT + 2))
  for p in $NATS_PORT $LISTEN $HTTP; do
    if taken "$p"; then echo "bench-memory-cluster: port $p is taken; set BGKMAP_BENCH_PORT" >&2; exit 1; fi
  done
  rm -rf "$OUT/js"
  printf 'listen: 127.0.0.1:%s\nmax_payload: 8MB\njetstream { store_dir: "%s", max_memory_store: 256MB }\n' \
    "$NATS_PORT" "$OUT/js" >"$OUT/nats.conf"
  nats-server -c "$OUT/nats.conf" >"$OUT/nats.log" 2>&1 &
  NATS=$!
  PIDS+=("$NATS")
  for _ in $(seq 100); do taken "$NATS_PORT" && break; sleep 0.1; done
  "$BUILD/server/bgkmapd" --config "$config" --listen "127.0.0.1:$LISTEN" --http "127.0.0.1:$HTTP" \
    --set cluster.node=a --set "cluster.nats=nats://127.0.0.1:$NATS_PORT" --set cluster.replicas=1 \
    --set "cluster.key_file=$OUT/cluster.key" --log-level warn >"$OUT/shard.log" 2>&1 &
  SHARD=$!
  PIDS+=("$SHARD")
  for _ in $(seq 300); do "$BUILD/tools/bgkmap/bgkmap" info --server "127.0.0.1:$LISTEN" >/dev/null 2>&1 && break; sleep 0.1; done
  r0=$(rss_kb "$SHARD")
  "$BUILD/tools/bgkmap/bgkmap" insert --server "127.0.0.1:$LISTEN" --robot r "$input" >/dev/null
  t1=$(date +%s%N)
  # A scrape shows the counts its previous scrape gathered; Info gathers them at once
  # (docs/scale-out.md, "Info on a shard").
  info() { "$BUILD/tools/bgkmap/bgkmap" info --server "127.0.0.1:$LISTEN" >/dev/null; }
  for _ in $(seq 600); do info && [ "$(metric bgkmap_map_version)" = "$n" ] && break; sleep 0.1; done
  r1=$(rss_kb "$SHARD")
  r2=$(idle_rss_kb "$SHARD" "$t1")
  info
  known=$(metric bgkmap_map_known_cells)
  awk -v s="${SET%%:*}" -v k="$known" -v r0="$r0" -v r1="$r1" -v r2="$r2" \
    'BEGIN {printf "%s, cluster shard: %d known cells; RSS %.1f MB before, %.1f MB once applied, %.1f MB idle (+%.1f MB = %.1f B/known cell)\n",
    s, k, r0 / 1024, r1 / 1024, r2 / 1024, (r2 - r0) / 1024, (r2 - r0) * 1024 / k}'
  kill -INT "$SHARD"; wait "$SHARD" || true
  kill "$NATS"; wait "$NATS" || true
  PIDS=()
done
