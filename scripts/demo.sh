#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install, build, start bgkmapd on loopback with the
# default config and a persistent store, stream the real Ouster street scans to it as one robot,
# query the mapped region into a GeoTIFF + PNG preview under out/, print the map's info, export
# the map as one archive, then restart the server on its store and check that the reloaded map
# answers exactly as before.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
bash scripts/configure.sh build  # as scripts/test.sh: after it, nothing to build
cmake --build build -j"$(nproc)" --target bgkmap bgkmapd

DATA="${BGKMAP_DATA:-../shared/data}/ouster_os1_128_street"
ADDR="127.0.0.1:${BGKMAP_PORT:-50551}"
HTTP_ADDR="127.0.0.1:${BGKMAP_HTTP_PORT:-50552}"  # /metrics and the live web map (docs/webmap.md)
BIN=build/tools/bgkmap/bgkmap
STORE=out/street-store
mkdir -p out
rm -rf "$STORE"

SERVER=
start_server() {
  build/server/bgkmapd --config config/default.yaml --listen "$ADDR" --data-dir "$STORE" \
    --http "$HTTP_ADDR" >>out/bgkmapd.log 2>&1 &
  SERVER=$!
  for _ in $(seq 200); do
    "$BIN" info --server "$ADDR" >/dev/null 2>&1 && return 0
    sleep 0.05
  done
  echo "demo: bgkmapd did not start; see out/bgkmapd.log" >&2
  return 1
}
stop_server() {
  kill -TERM "$SERVER"
  wait "$SERVER"
  SERVER=
}
trap '[ -n "$SERVER" ] && kill -TERM $SERVER 2>/dev/null; wait 2>/dev/null || true' EXIT
: >out/bgkmapd.log

start_server
echo "demo: live web map at http://$HTTP_ADDR/ while the demo runs (afterwards:" \
     "build/server/bgkmapd --data-dir $STORE --http $HTTP_ADDR)"
"$BIN" insert "$DATA" --server "$ADDR" --robot ouster
"$BIN" query --server "$ADDR" --out out/street.tif --png out/street.png
"$BIN" points --server "$ADDR" 8,0 -8,0 0,20 | tee out/points.json
"$BIN" info --server "$ADDR" >out/info.json && echo "demo: map info in out/info.json"
"$BIN" export --server "$ADDR" out/street.bgkmap
stop_server

start_server
"$BIN" points --server "$ADDR" 8,0 -8,0 0,20 >out/points-reloaded.json
stop_server
trap - EXIT
if ! cmp -s out/points.json out/points-reloaded.json; then
  echo "demo: the map reloaded from $STORE answers differently (out/points*.json)" >&2
  exit 1
fi
echo "demo: wrote out/street.tif (bands elevation, elevation_variance, traversability," \
     "traversability_variance, state), out/street.png and the archive out/street.bgkmap;" \
     "the map persisted in $STORE answered the same after a restart; server log in out/bgkmapd.log;" \
     "see it in a browser: build/server/bgkmapd --data-dir $STORE --http $HTTP_ADDR, then" \
     "open http://$HTTP_ADDR/"
