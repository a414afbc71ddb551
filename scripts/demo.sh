#!/usr/bin/env bash
# The main job on a fresh Debian 12 machine: install dependencies, build, and map the real
# Ouster street scans into a GeoTIFF and a PNG preview under out/.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build -G Ninja -DCMAKE_BUILD_TYPE=Release >/dev/null
cmake --build build -j"$(nproc)" --target bgkmap
mkdir -p out
DATA="${BGKMAP_DATA:-../shared/data}/ouster_os1_128_street"
build/tools/bgkmap/bgkmap build "$DATA" --config config/default.yaml \
  --out out/street.tif --png out/street.png
echo "demo: wrote out/street.tif (GeoTIFF: elevation, elevation_variance, traversability," \
     "traversability_variance, state) and out/street.png"
