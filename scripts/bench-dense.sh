#!/usr/bin/env bash
# Per-scan cost of dense real scans (docs/benchmarks.md, "Dense scans", issue 28): `bgkmap build`
# on one thread of the shared KITTI HDL-64E drive, the Ouster OS1-128 street scans and the hall,
# each with its robot's settings, ROUNDS times alternating a BASE binary (e.g. main's) and this
# checkout's, so both see the same load. Prints per dataset the medians per scan of the engine's
# stages (in-process stopwatches), of the whole process's wall time and CPU (user + sys), their
# ratios, whether the two GeoTIFFs are the same map (scripts/same-geotiff.sh), and the load average
# before and after.
#   scripts/bench-dense.sh BASE_BGKMAP [ROUNDS=5]
set -euo pipefail
cd "$(dirname "$0")/.."
base="$1"
rounds="${2:-5}"
data="${BGKMAP_SHARED_DATA:-../shared/data}"
bash scripts/configure.sh build
cmake --build build -j"$(nproc)" --target bgkmap
new=build/tools/bgkmap/bgkmap
out=out/bench/dense
mkdir -p "$out"
median() { sort -g | awk '{a[NR] = $1} END {print (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2}'; }
echo "load average before: $(cut -d' ' -f1-3 /proc/loadavg)"
for set in kitti_raw_0048:car_kitti ouster_os1_128_street:car_ouster balm_hall:handheld_hall; do
  input="$data/${set%%:*}"
  config="experiments/robots/${set##*:}.yaml"
  : >"$out/times"
  for ((r = 0; r < rounds; r++)); do
    for which in base new; do
      bin="$base"
      [ "$which" = new ] && bin="$new"
      start=$(date +%s%N)
      line=$(/usr/bin/time -f "%U %S" -o "$out/cpu" "$bin" build "$input" --config "$config" \
        --threads 1 --out "$out/$which.tif" 2>&1 | grep '^bgkmap build:')
      end=$(date +%s%N)
      # "bgkmap build: N scans, ... (CPU: elevation E s, features F s, traversability T s)"
      echo "$which $(((end - start) / 1000000)) $(awk '{print ($1 + $2) * 1000}' "$out/cpu") $(
        echo "$line" | sed -E 's/^bgkmap build: ([0-9]+) scans.*elevation ([0-9.]+) s, features ([0-9.]+) s, traversability ([0-9.]+) s.*/\1 \2 \3 \4/')" \
        >>"$out/times"
    done
  done
  scans=$(awk 'NR == 1 {print $4}' "$out/times")
  same=$(scripts/same-geotiff.sh "$out/base.tif" "$out/new.tif")
  printf '%s (%s scans, %s): per scan, medians of %s alternating runs\n' "${set%%:*}" "$scans" \
    "$config" "$rounds"
  printf '  %-6s %10s %10s %10s %10s %10s %10s\n' "" elevation features trav. engine wall CPU
  for which in base new; do
    m() { awk -v w="$which" -v c="$1" '$1 == w {print $c}' "$out/times" | median; }
    awk -v w="$which" -v n="$scans" -v e="$(m 5)" -v f="$(m 6)" -v t="$(m 7)" -v wall="$(m 2)" \
      -v cpu="$(m 3)" 'BEGIN {printf "  %-6s %8.2f ms %7.2f ms %7.2f ms %7.2f ms %7.1f ms %7.1f ms\n",
        w, e * 1000 / n, f * 1000 / n, t * 1000 / n, (e + f + t) * 1000 / n, wall / n, cpu / n}'
  done
  echo "  GeoTIFFs: $same"
done | tee "$out/result.txt"
echo "load average after: $(cut -d' ' -f1-3 /proc/loadavg)"
