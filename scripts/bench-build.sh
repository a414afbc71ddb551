#!/usr/bin/env bash
# `bgkmap build` of the shared KITTI drive on 1 and on 2 threads (docs/benchmarks.md, "Offline
# build on every core"): ROUNDS runs each, alternating, the median wall time of each and their
# ratio, and that the two GeoTIFFs are the same bytes. Run it on an otherwise idle machine: it
# prints the load average before and after, and the median CPU (user + sys) of each, which is
# what a loaded machine still measures (the 1-thread build's CPU is its wall time when idle).
#   scripts/bench-build.sh [ROUNDS=5] [INPUT=../shared/data/kitti_raw_0048]
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-5}"
input="${2:-${BGKMAP_SHARED_DATA:-../shared/data}/kitti_raw_0048}"
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap
out=out/bench/build
mkdir -p "$out"
load_before=$(cut -d' ' -f1-3 /proc/loadavg)
for ((r = 0; r < rounds; r++)); do
  for t in 1 2; do
    start=$(date +%s%N)
    /usr/bin/time -f "%U %S" -o "$out/cpu.$$" \
      build/tools/bgkmap/bgkmap -q build "$input" --threads "$t" --out "$out/t$t.tif" >/dev/null
    end=$(date +%s%N)
    cpu=$(awk '{printf "%d", ($1 + $2) * 1000}' "$out/cpu.$$")
    echo "$t $(((end - start) / 1000000)) $cpu" >>"$out/times.$$"  # milliseconds
  done
done
load_after=$(cut -d' ' -f1-3 /proc/loadavg)
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
one=$(awk '$1 == 1 {print $2}' "$out/times.$$" | median)
two=$(awk '$1 == 2 {print $2}' "$out/times.$$" | median)
cpu_one=$(awk '$1 == 1 {print $3}' "$out/times.$$" | median)
cpu_two=$(awk '$1 == 2 {print $3}' "$out/times.$$" | median)
rm -f "$out/times.$$" "$out/cpu.$$"
same=$(scripts/same-geotiff.sh "$out/t1.tif" "$out/t2.tif")
awk -v src="$input" -v a="$one" -v b="$two" -v n="$rounds" -v s="$same" -v ca="$cpu_one" \
  -v cb="$cpu_two" -v l0="$load_before" -v l1="$load_after" 'BEGIN {
  printf "%s: 1 thread %.2f s, 2 threads %.2f s (medians of %d), speed-up %.2fx; GeoTIFFs %s\n",
    src, a / 1000, b / 1000, n, a / b, s
  printf "CPU (user + sys): 1 thread %.2f s, 2 threads %.2f s; load average %s before, %s after\n",
    ca / 1000, cb / 1000, l0, l1 }' | tee "$out/result.txt"
