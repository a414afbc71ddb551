#!/usr/bin/env bash
# A dense robot on bgkmapd (docs/benchmarks.md, "A scan in bands on the server"): a KITTI-like
# drive streamed by `bgkmap insert` to a fresh in-memory bgkmapd with the car's settings, first at
# 10 Hz (each scan's time from received to applied: the mean and the histogram's p90 and p99
# buckets of `bgkmap_request_phase_seconds{phase="scan"}`), then as fast as it goes (scans/s, and
# the server's CPU per scan), for each variant of the server's settings, ROUNDS times alternating.
#   scripts/bench-dense-latency.sh [ROUNDS=3] [DRIVE=out/bench/dense-marginal/kitti-x7]
# The default drive is the 154-scan one scripts/bench-dense-marginal.sh lays out; any KITTI-like
# directory will do (../shared/data/kitti_raw_0048). VARIANTS, one per line of `--set` arguments
# (an empty line: the defaults), defaults to the four rows of the table.
set -euo pipefail
cd "$(dirname "$0")/.."
ROUNDS="${1:-3}"
DRIVE="${2:-out/bench/dense-marginal/kitti-x7}"
BUILD="${BUILD:-build}"
CONFIG=experiments/robots/car_kitti.yaml
DEFAULT_VARIANTS=$'\n--set server.scan_bands=0\n--set server.worker_cpus=[0,1]\n--set server.scan_bands=0 --set server.worker_cpus=[0,1]'
VARIANTS="${VARIANTS:-$DEFAULT_VARIANTS}"
PORT="${BGKMAP_BENCH_PORT:-57511}"
if [ ! -f "$DRIVE/poses.txt" ]; then
  echo "bench-dense-latency: $DRIVE is not a KITTI-like drive (scripts/bench-dense-marginal.sh makes the default)" >&2
  exit 1
fi
OUT="$(mktemp -d)"
SERVER=""
trap '[ -n "$SERVER" ] && kill -KILL "$SERVER" 2>/dev/null; rm -rf "$OUT"' EXIT
TCK=$(getconf CLK_TCK)
scans=$(find "$DRIVE/velodyne" -name '*.bin' | wc -l)

# Starts a fresh bgkmapd with the variant's arguments ($@), waiting for its HTTP port.
start_server() {
  PORT=$((PORT + 2))
  "$BUILD/server/bgkmapd" --config "$CONFIG" --listen "127.0.0.1:$PORT" \
    --http "127.0.0.1:$((PORT + 1))" --log-level warn "$@" >"$OUT/server.log" 2>&1 &
  SERVER=$!
  for _ in $(seq 300); do
    (echo >"/dev/tcp/127.0.0.1/$((PORT + 1))") 2>/dev/null && return 0
    sleep 0.1
  done
  echo "bench-dense-latency: bgkmapd did not start:" >&2
  cat "$OUT/server.log" >&2
  exit 1
}
stop_server() {
  kill -INT "$SERVER"
  wait "$SERVER" || true
  SERVER=""
}
insert() {
  "$BUILD/tools/bgkmap/bgkmap" insert --server "127.0.0.1:$PORT" --robot car "$@" "$DRIVE" \
    >/dev/null 2>"$OUT/client.log" || { cat "$OUT/client.log" >&2; exit 1; }
}

echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg); $scans scans of $DRIVE"
for round in $(seq "$ROUNDS"); do
  while IFS= read -r variant; do
    # shellcheck disable=SC2086  # the variant is a list of arguments
    start_server $variant
    insert --rate 10
    curl -s "http://127.0.0.1:$((PORT + 1))/metrics" | grep 'phase="scan"' >"$OUT/latency"
    stop_server
    # shellcheck disable=SC2086
    start_server $variant
    t0=$(date +%s%N)
    insert
    t1=$(date +%s%N)
    cpu=$(awk -v t="$TCK" '{print ($14 + $15) * 1000 / t}' "/proc/$SERVER/stat")
    stop_server
    python3 - "$OUT/latency" "${variant:-defaults}" "$round" "$scans" "$(((t1 - t0) / 1000000))" "$cpu" <<'PY'
import re, sys
path, variant, rnd, scans, wall_ms, cpu_ms = sys.argv[1:]
buckets, total, count = [], 0.0, 0.0
for line in open(path):
    m = re.search(r'le="([^"]+)"\} (\S+)', line)
    if m:
        buckets.append((float("inf") if m.group(1) == "+Inf" else float(m.group(1)), float(m.group(2))))
    elif "_sum" in line:
        total = float(line.split()[-1])
    elif "_count" in line:
        count = float(line.split()[-1])
def within(q):  # the smallest bucket holding a share q of the scans
    return next(le for le, n in buckets if n >= q * count)
n = int(scans)
print(f"{variant} (round {rnd}): 10 Hz received -> applied mean {1000 * total / count:.1f} ms, "
      f"p90 within {1000 * within(0.9):.0f} ms, p99 within {1000 * within(0.99):.0f} ms; "
      f"full speed {n / (int(wall_ms) / 1000):.1f} scans/s, server CPU {float(cpu_ms) / n:.1f} ms per scan")
PY
  done <<<"$VARIANTS"
done
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
