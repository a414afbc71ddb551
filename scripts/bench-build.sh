#!/usr/bin/env bash
# `bgkmap build` of the shared KITTI drive on 1 and on 2 threads (docs/benchmarks.md, "Offline
# build on every core"): ROUNDS runs each, alternating, the median wall time of each and their
# ratio, and that the two GeoTIFFs are the same bytes. Run it on an otherwise idle machine.
#   scripts/bench-build.sh [ROUNDS=5] [INPUT=../shared/data/kitti_raw_0048]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-5}"
input="${2:-${BGKMAP_SHARED_DATA:-../shared/data}/kitti_raw_0048}"
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap
out=out/bench/build
mkdir -p "$out"
for ((r = 0; r < rounds; r++)); do
  for t in 1 2; do
    start=$(date +%s%N)
    build/tools/bgkmap/bgkmap -q build "$input" --threads "$t" --out "$out/t$t.tif" >/dev/null
    end=$(date +%s%N)
    echo "$t $(((end - start) / 1000000))" >>"$out/times.$$"  # milliseconds
  done
done
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
one=$(awk '$1 == 1 {print $2}' "$out/times.$$" | median)
two=$(awk '$1 == 2 {print $2}' "$out/times.$$" | median)
rm -f "$out/times.$$"
cmp -s "$out/t1.tif" "$out/t2.tif" && same="the same bytes" || same="DIFFERENT"
awk -v src="$input" -v a="$one" -v b="$two" -v n="$rounds" -v s="$same" 'BEGIN {
  printf "%s: 1 thread %.2f s, 2 threads %.2f s (medians of %d), speed-up %.2fx; GeoTIFFs %s\n",
    src, a / 1000, b / 1000, n, a / b, s }' | tee "$out/result.txt"
