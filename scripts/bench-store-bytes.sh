#!/usr/bin/env bash
# Bytes a retained scan costs on disk and in the cluster's log (docs/benchmarks.md, "Store and
# log bytes per retained scan"): a sequence streamed by `bgkmap insert`, compact (the default) and
# --float32, to a persisting bgkmapd (the store's log and raw-scan families, from /metrics) and to
# a shard on one JetStream nats-server (the stream's bytes, from its monitoring port).
#   scripts/bench-store-bytes.sh [BUILD_DIR] [SEQUENCE_DIR] [ROBOT_CONFIG]
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD="${1:-build}"
SEQ="${2:-${BGKMAP_SHARED_DATA:-../shared/data}/kitti_raw_0048}"
CFG="${3:-experiments/robots/car_kitti.yaml}"
BIN="$BUILD/tools/bgkmap/bgkmap"
OUT="$(mktemp -d)"
PORT="${BGKMAP_BENCH_PORT:-57311}"
PIDS=()
trap 'for p in "${PIDS[@]}"; do kill -KILL "$p" 2>/dev/null || true; done; wait 2>/dev/null; rm -rf "$OUT"' EXIT
until_up() { for _ in $(seq 600); do "$@" >/dev/null 2>&1 && return 0; sleep 0.1; done; return 1; }
metric() { curl -s "http://127.0.0.1:$((PORT + 1))/metrics" | awk -v m="$1" '$1 == m {print $2}'; }
SCANS=$(ls "$SEQ"/velodyne | wc -l)

echo "| input | scans | log bytes/scan | raw-scan bytes/scan | retained bytes/scan |"
echo "|---|---|---|---|---|"
for mode in compact float32; do
  rm -rf "$OUT/store"
  extra=()
  [ "$mode" = float32 ] && extra=(--float32)
  # Stopped (SIGTERM) and started again so the families' bytes are what their files hold.
  "$BUILD/server/bgkmapd" -c "$CFG" -l "127.0.0.1:$PORT" --http "127.0.0.1:$((PORT + 1))" \
    --data-dir "$OUT/store" --log-level warn >"$OUT/server.log" 2>&1 &
  pid=$!
  PIDS+=("$pid")
  until_up curl -sf "http://127.0.0.1:$((PORT + 1))/metrics"
  "$BIN" insert "$SEQ" --server "127.0.0.1:$PORT" "${extra[@]}" >/dev/null 2>>"$OUT/insert.log"
  kill -TERM "$pid"
  wait "$pid" || true
  "$BUILD/server/bgkmapd" -c "$CFG" -l "127.0.0.1:$PORT" --http "127.0.0.1:$((PORT + 1))" \
    --data-dir "$OUT/store" --log-level warn >"$OUT/server.log" 2>&1 &
  pid=$!
  PIDS+=("$pid")
  until_up curl -sf "http://127.0.0.1:$((PORT + 1))/metrics"
  log=$(metric bgkmap_store_log_sst_bytes)
  raw=$(metric bgkmap_store_sources_sst_bytes)
  kill -TERM "$pid"
  wait "$pid" || true
  echo "| $mode | $SCANS | $((log / SCANS)) | $((raw / SCANS)) | $(((log + raw) / SCANS)) |"
done

# The cluster's log: what JetStream holds after each run.
printf 'max_payload: 8MB\n' >"$OUT/nats.conf"
nats-server -c "$OUT/nats.conf" -js -sd "$OUT/js" -p "$((PORT + 2))" -m "$((PORT + 3))" \
  >"$OUT/nats.log" 2>&1 &
PIDS+=($!)
until_up curl -sf "http://127.0.0.1:$((PORT + 3))/healthz?js-enabled-only=true"
(umask 077 && openssl rand -hex 32 >"$OUT/cluster.key")
"$BUILD/server/bgkmapd" -c "$CFG" -l "127.0.0.1:$PORT" --set cluster.node=a \
  --set "cluster.nats=nats://127.0.0.1:$((PORT + 2))" --set "cluster.key_file=$OUT/cluster.key" \
  --set cluster.insecure=true --log-level warn >"$OUT/shard.log" 2>&1 &
PIDS+=($!)
until_up "$BIN" info --server "127.0.0.1:$PORT"
stream_bytes() {
  curl -s "http://127.0.0.1:$((PORT + 3))/jsz?streams=true" | python3 -c '
import json, sys
d = json.load(sys.stdin)
print(sum(s["state"]["bytes"] for a in d.get("account_details", []) for s in a.get("stream_detail", [])))'
}
echo
echo "| input | scans | cluster log bytes/scan |"
echo "|---|---|---|"
before=$(stream_bytes)
"$BIN" insert "$SEQ" --server "127.0.0.1:$PORT" --robot compact >/dev/null 2>>"$OUT/insert.log"
after=$(stream_bytes)
echo "| compact | $SCANS | $(((after - before) / SCANS)) |"
"$BIN" insert "$SEQ" --server "127.0.0.1:$PORT" --robot float32 --float32 >/dev/null 2>>"$OUT/insert.log"
last=$(stream_bytes)
echo "| float32 | $SCANS | $(((last - after) / SCANS)) |"
