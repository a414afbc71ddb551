#!/usr/bin/env bash
# The cluster on one machine (docs/scale-out.md): a 3-node NATS JetStream cluster and 3 bgkmapd
# shards on loopback, the real street scans streamed by two robots (through two different
# shards), a query through a shard that owns none of the region, kill -9 of the region's owner,
# the takeover, and every answer compared byte for byte with a single bgkmapd fed the same scans.
# Everything it starts is stopped at exit; logs and GeoTIFFs go to out/cluster-demo/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap bgkmapd

DATA="${BGKMAP_DATA:-../shared/data}/ouster_os1_128_street"
OUT=out/cluster-demo
BIN=build/tools/bgkmap/bgkmap
BASE_PORT="${BGKMAP_CLUSTER_PORT:-52400}"
PARTITION_TILES=2  # 12.8 m partitions: the street spans dozens, so the demo crosses many
rm -rf "$OUT"
mkdir -p "$OUT"

PIDS=()
cleanup() {
  for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done
  wait 2>/dev/null || true
}
trap cleanup EXIT

# --- NATS: three servers, clustered, JetStream on each.
NATS_URLS=""
declare -A NATS_PID
start_nats() {
  local i=$1 routes="" j
  for j in 0 1 2; do
    [ "$j" = "$i" ] && continue
    routes+="${routes:+, }nats-route://127.0.0.1:$((BASE_PORT + 10 + j))"
  done
  cat >"$OUT/nats$i.conf" <<CONF
server_name: n$i
listen: 127.0.0.1:$((BASE_PORT + i))
max_payload: 8MB
jetstream { store_dir: "$OUT/nats$i", max_memory_store: 64MB }
cluster { name: bgkmap_demo, listen: 127.0.0.1:$((BASE_PORT + 10 + i)), routes: [$routes] }
CONF
  nats-server -c "$OUT/nats$i.conf" >>"$OUT/nats$i.log" 2>&1 &
  NATS_PID[$i]=$!
  PIDS+=($!)
}
for i in 0 1 2; do
  start_nats "$i"
  NATS_URLS+="${NATS_URLS:+,}nats://127.0.0.1:$((BASE_PORT + i))"
done

# --- Three shards and one single server (the reference).
declare -A SHARD_PID=() SHARD_ADDR=()
wait_up() {
  for _ in $(seq 600); do
    "$BIN" info --server "$1" >/dev/null 2>&1 && return 0
    sleep 0.05
  done
  echo "cluster-demo: $1 did not start; see $OUT/*.log" >&2
  return 1
}
# The cluster key every shard signs and checks the log, tile replies and membership with
# (docs/scale-out.md, "Trust"): a secret only the shards hold, readable by its owner only.
KEY="$OUT/cluster.key"
(umask 077 && openssl rand -hex 32 >"$KEY")
k=0
for n in a b c; do
  SHARD_ADDR[$n]="127.0.0.1:$((BASE_PORT + 20 + k))"
  k=$((k + 1))
  build/server/bgkmapd --listen "${SHARD_ADDR[$n]}" --set "cluster.node=$n" \
    --set "cluster.nats=$NATS_URLS" --set cluster.replicas=3 --set "cluster.key_file=$KEY" \
    --set "cluster.partition_tiles=$PARTITION_TILES" >"$OUT/shard-$n.log" 2>&1 &
  SHARD_PID[$n]=$!
  PIDS+=($!)
done
SINGLE="127.0.0.1:$((BASE_PORT + 30))"
build/server/bgkmapd --listen "$SINGLE" >"$OUT/single.log" 2>&1 &
PIDS+=($!)
for n in a b c; do wait_up "${SHARD_ADDR[$n]}"; done
wait_up "$SINGLE"
echo "cluster-demo: NATS cluster of 3 (JetStream, replicas 3) and shards a, b, c are up"

# A watch of the street's middle on shard c, which takes no scan: it learns of them from the log.
"$BIN" watch --server "${SHARD_ADDR[c]}" --bbox -20 -20 20 20 >"$OUT/watch-c.jsonl" \
  2>"$OUT/watch-c.err" &
WATCH_PID=$!
PIDS+=($!)
# The watch's call reaches shard c while the first robot streams: it sees at least that robot's
# later scans and the second robot's, whichever moment it subscribes.

# --- Two robots: r1 through shard a, r2 through shard b; the same order to the single server.
"$BIN" insert --server "${SHARD_ADDR[a]}" --robot r1 "$DATA" 2>&1 | tail -1
"$BIN" insert --server "${SHARD_ADDR[b]}" --robot r2 "$DATA" 2>&1 | tail -1
# Shard c learns of the scans as it reads the log: wait for the first update (a loaded machine
# may take seconds), never a fixed time.
for _ in $(seq 1200); do
  [ -s "$OUT/watch-c.jsonl" ] && break
  sleep 0.1
done
kill "$WATCH_PID" 2>/dev/null || true
UPDATES=$(wc -l <"$OUT/watch-c.jsonl")
if [ "$UPDATES" -eq 0 ]; then
  echo "cluster-demo: the watch on shard c received nothing in 120 s ($OUT/watch-c.err)" >&2
  exit 1
fi
echo "cluster-demo: a watch on shard c received $UPDATES tile updates of the scans sent to a and b"
"$BIN" insert --server "$SINGLE" --robot r1 "$DATA" >/dev/null
"$BIN" insert --server "$SINGLE" --robot r2 "$DATA" >/dev/null

# The region: the street's bounds as the single server knows them.
read -r X0 Y0 X1 Y1 < <("$BIN" info --server "$SINGLE" | python3 -c '
import json, sys
b = json.load(sys.stdin)["known_bounds"]
print(b["min_x"], b["min_y"], b["max_x"], b["max_y"])')

same() {  # same <label> <shard address> [bbox]: a region through a shard equals the single's
  local box=("$X0" "$Y0" "$X1" "$Y1")
  [ $# -gt 2 ] && box=("${@:3}")
  "$BIN" query --server "$2" --bbox "${box[@]}" --out "$OUT/$1.tif" >/dev/null
  "$BIN" query --server "$SINGLE" --bbox "${box[@]}" --out "$OUT/$1-single.tif" >/dev/null
  if cmp -s "$OUT/$1.tif" "$OUT/$1-single.tif"; then
    echo "cluster-demo: $1: [${box[*]}] through $2 is byte for byte the single server's"
  else
    echo "cluster-demo: $1: DIFFERS from the single server ($OUT/$1.tif)" >&2
    exit 1
  fi
}

# A partition of the street and its owner (bgkmap info on a shard lists what it serves); ask a
# shard that owns none of that partition for it, then for the whole street.
PART=""
for _ in $(seq 100); do
  for n in a b c; do
    PART=$("$BIN" info --server "${SHARD_ADDR[$n]}" | python3 -c '
import json, sys
owned = [p["name"] for p in json.load(sys.stdin)["cluster"]["owned"] if p["serving"]]
print(owned[0] if owned else "")')
    if [ -n "$PART" ]; then OWNER=$n; break 2; fi
  done
  sleep 0.1
done
OTHER=a
[ "$OWNER" = a ] && OTHER=b
echo "cluster-demo: partition $PART is owned by shard $OWNER; asking shard $OTHER"
EDGE=$(python3 -c "print(6.4 * $PARTITION_TILES)")  # metres: 64 cells of 0.1 m per tile
read -r PX0 PY0 PX1 PY1 < <(python3 -c "
px, py = map(int, '$PART'.split('.'))
e = $EDGE
print(px * e + 0.05, py * e + 0.05, (px + 1) * e - 0.05, (py + 1) * e - 0.05)")
same "partition-$PART-via-$OTHER" "${SHARD_ADDR[$OTHER]}" "$PX0" "$PY0" "$PX1" "$PY1"
same "street-via-$OTHER" "${SHARD_ADDR[$OTHER]}"

# --- kill -9 the owner; the others take its partitions (lease: cluster.lease_s).
SURVIVOR=c
[ "$OWNER" = c ] && SURVIVOR=a
kill -KILL "${SHARD_PID[$OWNER]}"
wait "${SHARD_PID[$OWNER]}" 2>/dev/null || true
KILLED_AT=$(date +%s.%N)
echo "cluster-demo: killed shard $OWNER (kill -9)"
same "after-kill" "${SHARD_ADDR[$SURVIVOR]}"
echo "cluster-demo: takeover: every partition answered again $(python3 -c "import time; print(f'{time.time() - $KILLED_AT:.2f}')") s after the kill"

# --- kill one NATS server: ingest and queries go on.
kill -KILL "${NATS_PID[0]}"
wait "${NATS_PID[0]}" 2>/dev/null || true
echo "cluster-demo: killed NATS server n0"
"$BIN" insert --server "${SHARD_ADDR[$SURVIVOR]}" --robot r3 "$DATA" 2>&1 | tail -1
"$BIN" insert --server "$SINGLE" --robot r3 "$DATA" >/dev/null
same "nats-down" "${SHARD_ADDR[$SURVIVOR]}"
echo "cluster-demo: done; logs and GeoTIFFs in $OUT/"
