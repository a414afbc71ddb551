#!/usr/bin/env bash
# Regenerates docs/results.md's measurements: the City experiment (Table 1 / Fig. 3 / Fig. 5)
# and the Fig. 1 protocol on the real airborne LAS against gdal_grid. Outputs go to $OUT.
# Usage: scripts/reproduce-paper.sh [build-dir] [out-dir]
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/out/paper}"
DATA="${BGKMAP_SHARED_DATA:-$ROOT/../shared/data}"
BGKMAP="$BUILD/tools/bgkmap/bgkmap"
cmake --build "$BUILD" -j2 --target bgkmap
mkdir -p "$OUT"
# City: 211 VLP-16 scans 1 m apart; ground-truth visibility from scans every 0.2 m (see results.md).
"$BGKMAP" simulate city --config "$ROOT/experiments/city.yaml" --truth-spacing 0.2 --out "$OUT/city"
"$BGKMAP" eval "$OUT/city" --config "$ROOT/experiments/city.yaml" --name City --out "$OUT/city_eval"
# Fig. 1 protocol on real airborne lidar, ground class only, seed 1.
"$BGKMAP" regress "$DATA/als_topography/topography.las" --classes 2 --seed 1 --out "$OUT/als_regress"
echo "reproduce-paper: results in $OUT"
