#!/usr/bin/env bash
# The cluster's benchmarks (docs/benchmarks.md, "Cluster"), on a simulated VLP-16 drive of 420 m
# (bgkmap simulate city, made once in out/bench/cluster-drive):
#   1. ingest: the rate at which 1 shard pinned to one core, and 2 shards pinned to one core each,
#      build the map from the log (every partition caught up with a log of the whole drive);
#   2. the added latency of a region query through a shard, inside one partition and across four,
#      against a single server with the same scans;
#   3. takeover: kill -9 of one of the 2 shards until the other answers for the whole drive.
# NATS (one server, JetStream) and the clients share the machine's cores with the shards.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap bgkmapd region_latency
BIN=build/tools/bgkmap/bgkmap
OUT=out/bench/cluster
DRIVE=out/bench/cluster-drive
PORT="${BGKMAP_BENCH_CLUSTER_PORT:-52600}"
LEASE=1
mkdir -p "$OUT"
[ -f "$DRIVE/poses.txt" ] || "$BIN" simulate city --out "$DRIVE" --length 420 --no-truth
SCANS=$(wc -l <"$DRIVE/poses.txt")

PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT
rm -rf "$OUT/js"
printf 'listen: 127.0.0.1:%s\nmax_payload: 8MB\njetstream { store_dir: "%s" }\n' "$PORT" \
  "$OUT/js" >"$OUT/nats.conf"
nats-server -c "$OUT/nats.conf" >"$OUT/nats.log" 2>&1 &
PIDS+=($!)
NATS="nats://127.0.0.1:$PORT"
wait_up() {
  for _ in $(seq 600); do "$BIN" info --server "$1" >/dev/null 2>&1 && return 0; sleep 0.05; done
  return 1
}
KEY="$OUT/cluster.key"  # the shards' cluster key (docs/scale-out.md, "Trust")
(umask 077 && openssl rand -hex 32 >"$KEY")
shard() {  # shard <name> <port> <core>: a shard pinned to one core, in the background
  taskset -c "$3" build/server/bgkmapd --listen "127.0.0.1:$2" --set "cluster.node=$1" \
    --set "cluster.nats=$NATS" --set "cluster.lease_s=$LEASE" --set server.worker_threads=1 \
    --set "cluster.key_file=$KEY" \
    --set "cluster.checkpoint_scans=${CHECKPOINT_SCANS:-100}" \
    --set server.query_threads=1 >"$OUT/shard-$1.log" 2>&1 &
  PIDS+=($!)
  LAST_PID=$!
}
# Seconds until every partition the shards took serves: the largest catch-up they logged, once
# every taken partition serves.
rebuilt() {
  local taken serving
  for _ in $(seq 1200); do
    sleep 0.25
    taken=$(cat "$@" | grep -c "event=partition_taken" || true)
    serving=$(cat "$@" | grep -c "event=partition_serving" || true)
    if [ "$taken" -gt 0 ] && [ "$taken" = "$serving" ]; then
      sleep 1  # nothing more is taken
      [ "$(cat "$@" | grep -c "event=partition_taken")" = "$taken" ] || continue
      cat "$@" | grep -o "catch_up_s=[0-9.]*" | cut -d= -f2 | sort -g | tail -1
      echo "$taken" >"$OUT/partitions"
      return 0
    fi
  done
  echo "bench-cluster: the shards did not catch up" >&2
  return 1
}

# The log: the drive through a loader shard, then the loader is gone.
shard loader $((PORT + 1)) 0
LOADER=$LAST_PID
wait_up "127.0.0.1:$((PORT + 1))"
"$BIN" insert --server "127.0.0.1:$((PORT + 1))" --robot r1 "$DRIVE" 2>&1 | tail -1 |
  tee "$OUT/append.txt"
kill -KILL "$LOADER"; wait "$LOADER" 2>/dev/null || true
sleep $((LEASE * 3))

# 1. One shard on core 0, then two on cores 0 and 1.
shard one $((PORT + 2)) 0
ONE=$LAST_PID
T1=$(rebuilt "$OUT/shard-one.log")
P1=$(cat "$OUT/partitions")
kill -KILL "$ONE"; wait "$ONE" 2>/dev/null || true
sleep $((LEASE * 3))
shard a $((PORT + 3)) 0
A=$LAST_PID
shard b $((PORT + 4)) 1
B=$LAST_PID
T2=$(rebuilt "$OUT/shard-a.log" "$OUT/shard-b.log")
PA=$(grep -c "event=partition_taken" "$OUT/shard-a.log")
PB=$(grep -c "event=partition_taken" "$OUT/shard-b.log")

# 2. Query latency: a single server with the same scans, and shard a.
build/server/bgkmapd --listen "127.0.0.1:$((PORT + 5))" >"$OUT/single.log" 2>&1 &
PIDS+=($!)
wait_up "127.0.0.1:$((PORT + 5))"
"$BIN" insert --server "127.0.0.1:$((PORT + 5))" --robot r1 "$DRIVE" 2>&1 | tail -1 |
  tee "$OUT/single-insert.txt"
# Partitions are 8 tiles = 51.2 m: the first box lies inside one, the second (same size)
# straddles x = 0 and y = 102.4, so four.
INSIDE="1 52 24 102"
ACROSS="-11.5 77.4 11.5 127.4"
{
  echo "| query | known cells | median ms | p95 ms |"
  echo "|---|---|---|---|"
  build/bench/region_latency --server "127.0.0.1:$((PORT + 5))" --bbox $INSIDE --label "single server, 23 x 50 m"
  build/bench/region_latency --server "127.0.0.1:$((PORT + 3))" --bbox $INSIDE --label "shard, inside one partition"
  build/bench/region_latency --server "127.0.0.1:$((PORT + 3))" --bbox $ACROSS --label "shard, across four partitions"
  build/bench/region_latency --server "127.0.0.1:$((PORT + 5))" --bbox $ACROSS --label "single server, the same 4-partition box"
} | tee "$OUT/query_latency.md"

# 3. Takeover: kill -9 b, then the whole drive through a.
kill -KILL "$B"
K0=$(date +%s.%N)
wait "$B" 2>/dev/null || true
build/bench/region_latency --server "127.0.0.1:$((PORT + 3))" --bbox -25 0 25 420 \
  --repetitions 1 --label takeover >/dev/null
K1=$(date +%s.%N)

RESTORED=$(grep "event=partition_taken" "$OUT/shard-a.log" | grep -vc "restored_from=0 " || true)
CKPT=$(cat "$OUT"/shard-*.log | grep -o "event=partition_checkpointed.*" | grep -o "seconds=[0-9.]*" |
  cut -d= -f2 | sort -g | awk '{a[NR]=$1} END {if (NR) printf "%d checkpoints written, median %.3f s, max %.3f s", NR, a[int((NR+1)/2)], a[NR]}')
echo "checkpoints: $CKPT; partitions a restored from a checkpoint at the takeover: $RESTORED" |
  tee "$OUT/checkpoints.txt"
python3 - "$SCANS" "$T1" "$T2" "$P1" "$PA" "$PB" "$K0" "$K1" "$LEASE" <<'PY' | tee "$OUT/summary.md"
import sys
scans, t1, t2, p1, pa, pb, k0, k1, lease = sys.argv[1:]
scans, t1, t2, k0, k1 = int(scans), float(t1), float(t2), float(k0), float(k1)
print(f"| shards (one core each) | partitions | rebuild s | scans/s |")
print(f"|---|---|---|---|")
print(f"| 1 | {p1} | {t1:.2f} | {scans / t1:.0f} |")
print(f"| 2 | {pa} + {pb} | {t2:.2f} | {scans / t2:.0f} |")
print(f"\nspeed-up 2 shards / 1 shard: {t1 / t2:.2f}x")
print(f"takeover: the whole drive answered through a {k1 - k0:.2f} s after kill -9 of b "
      f"(cluster.lease_s = {lease})")
PY
