#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install, build, start bgkmapd on loopback with the
# default config, stream the real Ouster street scans to it as one robot, query the mapped
# region into a GeoTIFF + PNG preview under out/, print the map's info, and stop the server.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target bgkmap bgkmapd

DATA="${BGKMAP_DATA:-../shared/data}/ouster_os1_128_street"
ADDR="127.0.0.1:${BGKMAP_PORT:-50551}"
BIN=build/tools/bgkmap/bgkmap
mkdir -p out

build/server/bgkmapd --config config/default.yaml --listen "$ADDR" >out/bgkmapd.log 2>&1 &
SERVER=$!
trap 'kill -TERM $SERVER 2>/dev/null || true; wait $SERVER 2>/dev/null || true' EXIT

"$BIN" insert "$DATA" --server "$ADDR" --robot ouster
"$BIN" query --server "$ADDR" --out out/street.tif --png out/street.png
"$BIN" points --server "$ADDR" 8,0 -8,0 0,20
"$BIN" info --server "$ADDR" >out/info.json && echo "demo: map info in out/info.json"

kill -TERM $SERVER
wait $SERVER
trap - EXIT
echo "demo: wrote out/street.tif (bands elevation, elevation_variance, traversability," \
     "traversability_variance, state) and out/street.png; server log in out/bgkmapd.log"
