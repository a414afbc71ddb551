#!/usr/bin/env bash
# The issue 14 street evaluation protocol (docs/results.md, "Real street scans (issue 14
# protocol)") on the real Ouster OS1-128 street scans, end to end:
#   1. ground truth from ALL points of ALL scans           -> $OUT/truth/ground_truth.tif
#   2. the maps' input: every 4th record of each scan file -> $OUT/thin4 (primary protocol)
#   3. bgkmap eval of every method against the truth       -> $OUT/eval/{eval.json,table.md}
# and, as checks on the protocol (not the primary numbers): the three other quarters of the
# returns (--offset 1..3, $OUT/eval_offset{1,2,3}) and leave-one-scan-out (the map from scans 0
# and 2, $OUT/eval_scans02). The map parameters are experiments/street.yaml, fixed a priori.
# Usage: scripts/street-eval.sh [build-dir] [out-dir]
set -euo pipefail
ROOT="$(cd "$(dirname "$0")/.." && pwd)"
BUILD="${1:-$ROOT/build}"
OUT="${2:-$ROOT/out/street}"
DATA="${BGKMAP_SHARED_DATA:-$ROOT/../shared/data}"
SEQ="$DATA/ouster_os1_128_street"
CONFIG="$ROOT/experiments/street.yaml"
BGKMAP="$BUILD/tools/bgkmap/bgkmap"
KEEP_EVERY=4
cmake --build "$BUILD" -j2 --target bgkmap
rm -rf "$OUT"
mkdir -p "$OUT"
stage() { echo "street-eval: $1 ($SECONDS s so far)"; }

stage "ground truth from all points of all scans"
"$BGKMAP" truth "$SEQ" --config "$CONFIG" --out "$OUT/truth"

stage "primary: the maps get every ${KEEP_EVERY}th record of each scan (offset 0), all methods"
"$BGKMAP" thin "$SEQ" --keep-every "$KEEP_EVERY" --offset 0 --out "$OUT/thin4"
"$BGKMAP" eval "$OUT/thin4" --truth "$OUT/truth/ground_truth.tif" --config "$CONFIG" \
  --name street --out "$OUT/eval"

stage "checks: the other quarters of the returns, and leave-one-scan-out"
for offset in 1 2 3; do
  "$BGKMAP" thin "$SEQ" --keep-every "$KEEP_EVERY" --offset "$offset" --out "$OUT/thin4_$offset"
  "$BGKMAP" eval "$OUT/thin4_$offset" --truth "$OUT/truth/ground_truth.tif" --config "$CONFIG" \
    --name "street offset $offset" --no-figures --out "$OUT/eval_offset$offset" > /dev/null
done
"$BGKMAP" thin "$SEQ" --scans 0,2 --out "$OUT/scans02"
"$BGKMAP" eval "$OUT/scans02" --truth "$OUT/truth/ground_truth.tif" --config "$CONFIG" \
  --name "street scans 0,2" --no-figures --out "$OUT/eval_scans02" > /dev/null

stage "done"
echo "street-eval: primary table $OUT/eval/table.md; checks in $OUT/eval_offset*/ and $OUT/eval_scans02/"
