#!/usr/bin/env bash
# Memory per known cell on a larger map (docs/benchmarks.md, "Memory per known cell"): the
# simulated VLP-16 robots of bench/server_load (its ingest phase: 1, then 4, then 16 robots at
# once, each on its own street; killed when the latency phase starts, so a few more scans may
# land) into a fresh in-memory bgkmapd with storage.dense_tiles_mb DENSE_MB; then the resident
# set's growth and the tile memory per known cell, and the ingest rates.
#   scripts/bench-memory-sim.sh DENSE_MB [PORT=57700] (SCANS=48 scans per robot)
# Needs build/server/bgkmapd and build/bench/server_load.
set -u
cd "$(dirname "$0")/.."
mb=$1; PORT=${2:-57700}; HTTP=$((PORT + 1))
OUT="$(mktemp)"
trap 'rm -f "$OUT"' EXIT
build/server/bgkmapd --set "storage.dense_tiles_mb=$mb" --listen 127.0.0.1:$PORT --http 127.0.0.1:$HTTP --log-level warn >/dev/null 2>&1 &
S=$!
for _ in $(seq 100); do (echo >"/dev/tcp/127.0.0.1/$HTTP") 2>/dev/null && break; sleep 0.1; done
r0=$(awk '/^VmRSS:/ {print $2}' /proc/$S/status)
build/bench/server_load --server 127.0.0.1:$PORT --scans-per-robot ${SCANS:-48} --queries 5 >"$OUT" 2>/dev/null &
L=$!
t0=$(date +%s)
while [ "$(grep -c '^| 16 ' "$OUT")" = 0 ] && kill -0 $L 2>/dev/null; do sleep 0.5; done
t1=$(date +%s)
kill $L 2>/dev/null; wait $L 2>/dev/null
metric() { curl -s "http://127.0.0.1:$HTTP/metrics" | awk -v k="$1" '$1 == k {print $2}'; }
prev=-1; same=0
for _ in $(seq 200); do b=$(metric bgkmap_map_tile_memory_bytes); if [ "$b" = "$prev" ]; then same=$((same+1)); else same=0; fi; [ $same -ge 4 ] && break; prev=$b; sleep 0.5; done
# Idle: the workers hand their engine scratch back 2 s after the last change; wait for a
# resident set unchanged for 2 s, at least 3 s after the ingest.
rprev=-1; same=0
for _ in $(seq 200); do r1=$(awk '/^VmRSS:/ {print $2}' /proc/$S/status); if [ "$r1" = "$rprev" ]; then same=$((same+1)); else same=0; fi; [ $same -ge 4 ] && [ $(($(date +%s) - t1)) -ge 3 ] && break; rprev=$r1; sleep 0.5; done
echo "tiles_packed_total $(metric bgkmap_map_tiles_packed_total)"; k=$(metric bgkmap_map_known_cells); t=$(metric bgkmap_map_tiles); p=$(metric bgkmap_map_packed_tiles)
head -6 "$OUT"
awk -v mb=$mb -v r0=$r0 -v r1=$r1 -v k=$k -v b=$prev -v t=$t -v p=$p -v s=$((t1 - t0)) 'BEGIN {printf "simulated VLP-16 (server_load ingest) dense_tiles_mb %s: %d known cells, %d tiles (%d packed); RSS +%.1f MB = %.1f B/known cell; tiles %.1f MB = %.1f B/known cell; ingest %d s\n", mb, k, t, p, (r1-r0)/1024, (r1-r0)*1024/k, b/1048576, b/k, s}'
kill -INT $S; wait $S
