#!/usr/bin/env bash
# Regenerates docs/results.md's measurements: City and Aerial (Table 1 / Fig. 3 / Fig. 5), the
# Fig. 1 protocol on the real airborne LAS against gdal_grid, and the large (~10M points) case
# simulated on the real DEM against gdal_grid. Outputs go to $OUT.
# Usage: scripts/reproduce-paper.sh [build-dir] [out-dir]
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/out/paper}"
DATA="${BGKMAP_SHARED_DATA:-$ROOT/../shared/data}"
DEM="$DATA/dem/topography_ground_1m.asc"
BGKMAP="$BUILD/tools/bgkmap/bgkmap"
cmake --build "$BUILD" -j2 --target bgkmap
mkdir -p "$OUT"
stage() { echo "reproduce-paper: $1 ($SECONDS s so far)"; }

stage "City: 211 VLP-16 scans 1 m apart; ground-truth visibility from scans every 0.2 m"
"$BGKMAP" simulate city --config "$ROOT/experiments/city.yaml" --truth-spacing 0.2 --out "$OUT/city"
"$BGKMAP" eval "$OUT/city" --config "$ROOT/experiments/city.yaml" --name City --out "$OUT/city_eval"

stage "Aerial: 13 x 13 HDL-32E scans 10 m apart; ground-truth visibility from scans every 2.5 m"
"$BGKMAP" simulate aerial --dem "$DEM" --config "$ROOT/experiments/aerial.yaml" \
  --truth-spacing 2.5 --out "$OUT/aerial"
"$BGKMAP" eval "$OUT/aerial" --config "$ROOT/experiments/aerial.yaml" --name Aerial \
  --out "$OUT/aerial_eval"

stage "Fig. 1 protocol on real airborne lidar, ground class only, seed 1"
"$BGKMAP" regress "$DATA/als_topography/topography.las" --classes 2 --seed 1 --out "$OUT/als_regress"

# Large case: every point of a 16 x 16 HDL-32E flight over the DEM (~10M points). The CV grid
# brackets the Aerial map (0.2 m cells, l = 1 m); global invdist is O(cells x points) and skipped.
stage "Large case: ~10M simulated points vs gdal_grid invdistnn and linear"
"$BGKMAP" simulate aerial --dem "$DEM" --grid 16 --no-truth --out "$OUT/large"
"$BGKMAP" regress "$OUT/large" --seed 1 --folds 3 --resolutions 0.2,0.5,1 \
  --kernel-lengths 0.25,0.5,1,2 --peers invdistnn,linear --out "$OUT/large_regress"
rm -f "$OUT/large_regress/train.csv"  # 130 MB of training points, only gdal_grid's input

stage "done"
echo "reproduce-paper: results in $OUT"
