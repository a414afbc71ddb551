#!/usr/bin/env bash
# Streams per region against one shared stream (docs/benchmarks.md, "Cluster: streams per
# region"; docs/scale-out.md). A fleet of ROBOTS (default 4) simulated VLP-16 robots, each
# driving 840 m of road (bgkmap simulate city, made once in out/bench/cluster-regions-drive) in
# its own part of the site, SPACING m (default 2000) apart in x; for 2 and 4 shards, each way
# (cluster.region_partitions 0, and REGION_PARTITIONS, default 8: regions of 410 m):
#   1. ingest: the robots' drives appended through one shard by `bgkmap insert` (compact scans,
#      one robot after the other), scans/s;
#   2. the shards build the map from the log: seconds until every partition serves, scans/s;
#   3. the bytes each shard's NATS connection received (its Info: the log, or the log's headers
#      and its regions' payloads, plus membership);
#   4. what JetStream stores: the log's and the region streams' bytes;
#   5. region query latency through a shard, inside one region and across a region border.
# One nats-server (JetStream, file storage) on the same machine; shards pinned to cores
# round-robin, so 4 shards share 2 cores: rates are the machine's, bytes are the design's.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap bgkmapd region_latency
BIN=build/tools/bgkmap/bgkmap
OUT=out/bench/cluster-regions
DRIVE=out/bench/cluster-regions-drive
PORT="${BGKMAP_BENCH_CLUSTER_PORT:-52700}"
REGION="${REGION_PARTITIONS:-8}"
LENGTH="${DRIVE_LENGTH:-840}"
ROBOTS="${ROBOTS:-4}"
SPACING="${SPACING:-2000}"
LEASE=1
CORES=$(nproc)
mkdir -p "$OUT"
[ -f "$DRIVE/poses.txt" ] || "$BIN" simulate city --out "$DRIVE" --length "$LENGTH" --no-truth
# Robot k's drive: the same scans, its poses moved k * SPACING m along x.
for k in $(seq 0 $((ROBOTS - 1))); do
  d="$DRIVE-r$k"
  [ -f "$d/poses.txt" ] && continue
  mkdir -p "$d"
  ln -sfn "$(realpath "$DRIVE/velodyne")" "$d/velodyne"
  cp "$DRIVE/times.txt" "$d/"
  awk -v dx=$((k * SPACING)) '{ $4 = $4 + dx; print }' "$DRIVE/poses.txt" >"$d/poses.txt"
done
SCANS=$(($(wc -l <"$DRIVE/poses.txt") * ROBOTS))

PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT
wait_up() {
  for _ in $(seq 600); do "$BIN" info --server "$1" >/dev/null 2>&1 && return 0; sleep 0.05; done
  echo "bench-cluster-regions: $1 did not come up" >&2
  return 1
}
dir_bytes() {  # dir_bytes <glob>: the bytes of the files under every directory it matches
  python3 -c 'import glob, os, sys
print(sum(os.path.getsize(os.path.join(r, f)) for d in glob.glob(sys.argv[1])
          for r, _, fs in os.walk(d) for f in fs))' "$1"
}
KEY="$OUT/cluster.key"
(umask 077 && openssl rand -hex 32 >"$KEY")

# run <region_partitions> <shards>: one line of results.
run() {
  local regions=$1 shards=$2 dir="$OUT/r$1-s$2"
  rm -rf "$dir" && mkdir -p "$dir"
  printf 'listen: 127.0.0.1:%s\nmax_payload: 8MB\njetstream { store_dir: "%s" }\n' "$PORT" \
    "$dir/js" >"$dir/nats.conf"
  nats-server -c "$dir/nats.conf" >"$dir/nats.log" 2>&1 &
  local nats_pid=$!
  PIDS+=("$nats_pid")
  local nats="nats://127.0.0.1:$PORT"
  shard() {  # shard <name> <port> <core>
    taskset -c "$3" build/server/bgkmapd --listen "127.0.0.1:$2" --set "cluster.node=$1" \
      --set "cluster.nats=$nats" --set "cluster.lease_s=$LEASE" --set "cluster.key_file=$KEY" \
      --set "cluster.region_partitions=$regions" --set server.worker_threads=1 \
      --set server.query_threads=1 >"$dir/shard-$1.log" 2>&1 &
    PIDS+=($!)
    LAST_PID=$!
  }
  # 1. The drive through a loader shard, then the loader is gone.
  shard loader $((PORT + 1)) 0
  local loader=$LAST_PID
  wait_up "127.0.0.1:$((PORT + 1))"
  local t0 t1
  t0=$(date +%s.%N)
  for k in $(seq 0 $((ROBOTS - 1))); do
    "$BIN" insert --server "127.0.0.1:$((PORT + 1))" --robot "r$k" "$DRIVE-r$k" >>"$dir/insert.txt" 2>&1
  done
  t1=$(date +%s.%N)
  kill -KILL "$loader"; wait "$loader" 2>/dev/null || true
  sleep $((LEASE * 3))
  # 2. The shards, started together, until every partition serves.
  local logs=() ports=()
  for i in $(seq 0 $((shards - 1))); do
    shard "s$i" $((PORT + 10 + i)) $((i % CORES))
    logs+=("$dir/shard-s$i.log")
    ports+=($((PORT + 10 + i)))
  done
  for p in "${ports[@]}"; do wait_up "127.0.0.1:$p"; done
  local b0 b1 taken serving
  b0=$(date +%s.%N)
  for _ in $(seq 2400); do
    sleep 0.25
    taken=$(cat "${logs[@]}" | grep -c "event=partition_taken" || true)
    serving=$(cat "${logs[@]}" | grep -c "event=partition_serving" || true)
    if [ "$taken" -gt 0 ] && [ "$taken" = "$serving" ]; then
      sleep 1
      [ "$(cat "${logs[@]}" | grep -c "event=partition_taken")" = "$taken" ] && break
    fi
  done
  b1=$(date +%s.%N)
  local build_s
  build_s=$(cat "${logs[@]}" | grep -o "catch_up_s=[0-9.]*" | cut -d= -f2 | sort -g | tail -1)
  # 3. What each shard received, and what each owns.
  local received="" owned=""
  for p in "${ports[@]}"; do
    "$BIN" info --server "127.0.0.1:$p" >"$dir/info-$p.json"
    received+="$(python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["cluster"]["nats_received_bytes"])' "$dir/info-$p.json") "
    owned+="$(python3 -c 'import json,sys; print(len(json.load(open(sys.argv[1]))["cluster"]["owned"]))' "$dir/info-$p.json") "
  done
  # 4. What JetStream stores (the streams' directories).
  local log_bytes region_bytes
  log_bytes=$(dir_bytes "$dir/js/jetstream/*/streams/BGKMAP_LOG")
  region_bytes=$(dir_bytes "$dir/js/jetstream/*/streams/BGKMAP_REGION_*")
  # 5. Query latency through shard s0, both ways on the same boxes: inside region (0, 0)
  # (x 1..24, y 52..102) and across its border with region (0, 1) at y = REGION / 2 partitions
  # of 51.2 m (102.4 m for 4).
  local border lat_in lat_across
  border=$(python3 -c "print($REGION // 2 * 51.2)")
  lat_in=$(build/bench/region_latency --server "127.0.0.1:${ports[0]}" --bbox 1 52 24 102 --label in)
  lat_across=$(build/bench/region_latency --server "127.0.0.1:${ports[0]}" --bbox 1 \
    "$(python3 -c "print($border - 25)")" 24 "$(python3 -c "print($border + 25)")" --label across)
  python3 - "$regions" "$shards" "$SCANS" "$t0" "$t1" "$b0" "$b1" "$build_s" "$received" \
    "$owned" "$log_bytes" "$region_bytes" "$lat_in" "$lat_across" <<'PY' | tee -a "$OUT/results.md"
import sys
(regions, shards, scans, t0, t1, b0, b1, build_s, received, owned, log_b, region_b, lat_in,
 lat_across) = sys.argv[1:]
scans = int(scans)
append = scans / (float(t1) - float(t0))
build = float(build_s) if build_s else float(b1) - float(b0)
rec = [int(x) / 1e6 for x in received.split()]
own = owned.split()
med = lambda row: row.split("|")[3].strip()
print(f"| {'one stream' if regions == '0' else 'regions of ' + regions + ' x ' + regions} "
      f"| {shards} | {append:.0f} | {build:.2f} s, {scans / build:.0f} | "
      f"{' / '.join(f'{r:.1f}' for r in rec)} | {' / '.join(own)} | "
      f"{int(log_b) / 1e6:.1f} + {int(region_b) / 1e6:.1f} | {med(lat_in)} | {med(lat_across)} |")
PY
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
  PIDS=()
  sleep 1
}

{
  echo
  echo "$(date -u +%F): $ROBOTS robots, $SCANS scans, $LENGTH m each, $SPACING m apart;" \
    "region_partitions $REGION; $CORES cores"
  echo
  echo "| stream | shards | append scans/s | build from the log | MB each shard received | partitions each | stored MB (log + regions) | query in one region, median ms | across a border, median ms |"
  echo "|---|---|---|---|---|---|---|---|---|"
} | tee -a "$OUT/results.md"
for shards in 2 4; do
  run 0 "$shards"
  run "$REGION" "$shards"
done
