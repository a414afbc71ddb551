#!/usr/bin/env bash
# What a scan costs `bgkmap build` on a long drive (docs/benchmarks.md, "Dense scans", issue 28):
# the whole process's wall time for the first half of each shared real sequence with at least 6
# scans (KITTI HDL-64E, the hall) and for all of it, ROUNDS times alternating, default threads
# and the robot's settings. A short drive's ms per scan carries the fixed part (process start,
# the GeoTIFF); the marginal (T_all - T_half) / (N - N_half) is the part that every further scan
# of a long drive pays. Then a long drive of real scans: the KITTI drive laid 7 times, 140 m
# apart along x (its 60 m range never reaches the next copy), 154 scans as the issue's drive, its
# whole process per scan.
#   scripts/bench-dense-marginal.sh [BGKMAP=build/tools/bgkmap/bgkmap] [ROUNDS=5]
set -euo pipefail
cd "$(dirname "$0")/.."
bin="${1:-build/tools/bgkmap/bgkmap}"
rounds="${2:-5}"
data="$(realpath "${BGKMAP_SHARED_DATA:-../shared/data}")"
out=out/bench/dense-marginal
rm -rf "$out"
mkdir -p "$out"
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
# The first N scans of a KITTI-like directory (velodyne/*.bin, poses.txt, times.txt if any).
first_scans() {
  local from="$1" n="$2" to="$3"
  mkdir -p "$to/velodyne"
  head -n "$n" "$from/poses.txt" >"$to/poses.txt"
  [ -f "$from/times.txt" ] && head -n "$n" "$from/times.txt" >"$to/times.txt"
  find "$from/velodyne" -name '*.bin' | sort | head -n "$n" | while read -r f; do
    ln -s "$f" "$to/velodyne/$(basename "$f")"
  done
}
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
for set in kitti_raw_0048:car_kitti balm_hall:handheld_hall; do
  input="$data/${set%%:*}"
  config="experiments/robots/${set##*:}.yaml"
  all=$(wc -l <"$input/poses.txt")
  half=$((all / 2))
  first_scans "$input" "$half" "$out/half-${set%%:*}"
  : >"$out/times"
  for ((r = 0; r < rounds; r++)); do
    for which in half all; do
      dir="$input"
      [ "$which" = half ] && dir="$out/half-${set%%:*}"
      start=$(date +%s%N)
      "$bin" build "$dir" --config "$config" --out "$out/$which.tif" --quiet >/dev/null
      end=$(date +%s%N)
      echo "$which $(((end - start) / 1000000))" >>"$out/times"
    done
  done
  t_half=$(awk '$1 == "half" {print $2}' "$out/times" | median)
  t_all=$(awk '$1 == "all" {print $2}' "$out/times" | median)
  awk -v s="${set%%:*}" -v h="$half" -v n="$all" -v th="$t_half" -v ta="$t_all" -v r="$rounds" \
    'BEGIN {printf "%s: %d scans %.0f ms (%.1f ms per scan), %d scans %.0f ms (%.1f ms per scan); marginal %.1f ms per scan (medians of %d)\n",
      s, h, th, th / h, n, ta, ta / n, (ta - th) / (n - h), r}'
done | tee "$out/result.txt"
# The KITTI drive 7 times over, each copy's poses 140 m further along x.
long="$out/kitti-x7"
mkdir -p "$long/velodyne"
kitti="$data/kitti_raw_0048"
k=0
for copy in 0 1 2 3 4 5 6; do
  awk -v dx=$((copy * 140)) '{$4 = $4 + dx; print}' "$kitti/poses.txt" >>"$long/poses.txt"
  for f in $(find "$kitti/velodyne" -name '*.bin' | sort); do
    ln -s "$f" "$long/velodyne/$(printf %06d.bin "$k")"
    k=$((k + 1))
  done
done
: >"$out/times"
for ((r = 0; r < rounds; r++)); do
  start=$(date +%s%N)
  "$bin" build "$long" --config experiments/robots/car_kitti.yaml --out "$out/long.tif" --quiet \
    >/dev/null
  end=$(date +%s%N)
  echo $(((end - start) / 1000000)) >>"$out/times"
done
t_long=$(median <"$out/times")
awk -v n="$k" -v t="$t_long" -v r="$rounds" 'BEGIN {printf "kitti_raw_0048 x 7, 140 m apart: %d scans %.0f ms, %.1f ms per scan (median of %d)\n", n, t, t / n, r}' |
  tee -a "$out/result.txt"
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
