#!/usr/bin/env bash
# A server that runs for months, compressed (issue 25; docs/testing.md, "Soak"): bgkmapd with a
# persistent store, retention on (storage.retention_mb, 64 MB here) and a checkpoint every 30 s;
# 4 robots stream the real Ouster street scans at 10 Hz each (looped, each on its own street),
# a reader queries regions and points every second, a watch follows each street. bench/soak.cc
# reads the store's bytes on disk every 250 ms and bgkmapd's resident set every 5 s and judges:
# the store stays under the sizing rule's bound (1.5 x retention + write-ahead log 64 MB +
# 3 x the map, which takes 16 MB stored, + 40 MB of flushes and RocksDB's own files), the
# resident set is flat (last quarter within 64 MB of the second), no scan is refused while
# space remains, every query answers.
#   scripts/soak.sh [SECONDS]        default 1800 (30 min); CI runs the 120 s smoke
# Environment: BGKMAP_DATA (../shared/data), BGKMAP_SOAK_ROBOTS (4), BGKMAP_SOAK_RATE (10 Hz),
# BGKMAP_SOAK_STRIDE (every n-th point of a scan, 1: whole scans), BGKMAP_SOAK_RETENTION_MB (64),
# BGKMAP_SOAK_OUT (out/soak: the samples, the verdict and the server's log).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-1800}"
data="${BGKMAP_DATA:-../shared/data}/ouster_os1_128_street"
robots="${BGKMAP_SOAK_ROBOTS:-4}"
rate="${BGKMAP_SOAK_RATE:-10}"
stride="${BGKMAP_SOAK_STRIDE:-1}"
retention_mb="${BGKMAP_SOAK_RETENTION_MB:-64}"
reserve_mb=16
out="${BGKMAP_SOAK_OUT:-out/soak}"
# The sizing rule of docs/storage.md without the reserve (kept free, not used): retention,
# half of it as journal between checkpoints, the write-ahead log (twice the 32 MB memory
# budget), three times the map (the street map the robots loop over stores in 16 MB), the
# memory budget for flushes and compactions, and 8 MB of RocksDB's own log and manifest.
map_mb=16
bound_mb=$((retention_mb * 3 / 2 + 64 + 3 * map_mb + 32 + 8))

if [ -z "${BGKMAP_SOAK_NO_BUILD:-}" ]; then  # set it to run what is built
  bash scripts/configure.sh build >/dev/null
  cmake --build build -j"$(nproc)" --target bgkmapd soak >/dev/null
fi
mkdir -p "$out"
store="$(mktemp -d)/store"
server=
cleanup() {
  [ -n "$server" ] && kill -TERM "$server" 2>/dev/null && wait "$server" 2>/dev/null
  rm -rf "$(dirname "$store")"
}
trap cleanup EXIT
build/server/bgkmapd --listen 127.0.0.1:0 --data-dir "$store" --worker-threads 2 \
  --set storage.retention_mb="$retention_mb" --set storage.checkpoint_interval_s=30 \
  --set storage.min_free_space_mb="$reserve_mb" >"$out/bgkmapd.log" 2>&1 &
server=$!
port=
for _ in $(seq 600); do
  port=$(sed -n 's/.*event=listening .*port=\([0-9]*\).*/\1/p' "$out/bgkmapd.log" | head -1)
  [ -n "$port" ] && break
  kill -0 "$server" 2>/dev/null || { echo "soak: bgkmapd exited; $out/bgkmapd.log" >&2; exit 1; }
  sleep 0.1
done
[ -n "$port" ] || { echo "soak: bgkmapd did not listen within 60 s" >&2; exit 1; }
echo "soak: $robots robots x $rate Hz for $seconds s, retention $retention_mb MB, bound $bound_mb MB"
status=0
build/bench/soak --server "127.0.0.1:$port" --scans "$data" --data-dir "$store" --pid "$server" \
  --robots "$robots" --rate "$rate" --seconds "$seconds" --stride "$stride" \
  --max-disk-mb "$bound_mb" --reserve-mb "$reserve_mb" | tee "$out/samples.csv" || status=$?
kill -TERM "$server"
if ! wait "$server"; then
  echo "soak: bgkmapd did not exit cleanly; $out/bgkmapd.log" >&2
  status=1
fi
server=
grep -c 'event=checkpoint ' "$out/bgkmapd.log" | sed 's/^/soak: checkpoints: /'
[ "$status" -eq 0 ] && echo "soak: passed" || echo "soak: FAILED (see $out/)" >&2
exit "$status"
