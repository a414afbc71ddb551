#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ with clang (ASan + UBSan, coverage) in build-fuzz/ and
# runs each one, one after the other, for SECONDS (default 60) from its committed seed corpus
# fuzz/corpus/<target>/; new inputs go to build-fuzz/corpus/<target>/, findings (crash-*,
# leak-*, oom-*, timeout-*) to build-fuzz/artifacts/. Prints each target's executions.
#   scripts/fuzz.sh [SECONDS] [TARGET...]      e.g. scripts/fuzz.sh 600 las_reader
#   scripts/fuzz.sh --seeds                    rewrite fuzz/corpus/ from the real encoders
# Exit status 1 if any target found something. docs/testing.md has the targets and results.
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
TARGETS=(scan_request compact_points tile_codec log_record map_archive las_reader pcd_reader
  scan_graph mcap_reader cdr_reader)
DIR=build-fuzz
bash scripts/install-deps.sh
CXX_CLANG=$(command -v clang++-14 || command -v clang++ || true)
[ -n "$CXX_CLANG" ] || { echo "fuzz: clang++ not found (apt-get install clang-14)" >&2; exit 2; }

# -O1 and line tables: what libFuzzer's manual recommends (fast enough, symbolised reports).
# Asserts stay on (no NDEBUG): they are checks the fuzzer should trip.
bash scripts/configure.sh "$DIR" -DCMAKE_CXX_COMPILER="$CXX_CLANG" -DBGKMAP_FUZZ=ON \
  -DBGKMAP_BUILD_TESTS=OFF -DBGKMAP_BUILD_BENCHMARKS=OFF -DBGKMAP_WERROR=OFF \
  "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -gline-tables-only"
start=$SECONDS
cmake --build "$DIR" -j"$(nproc)" --target fuzzers
echo "fuzz: built in $((SECONDS - start)) s"

if [ "${1:-}" = "--seeds" ]; then
  "$DIR/fuzz/make_fuzz_seeds" fuzz/corpus "$(cmake -LA -N "$DIR" |
    sed -n 's/^BGKMAP_SHARED_DATA:PATH=//p')"
  du -sh fuzz/corpus/*
  exit 0
fi

seconds=${1:-60}
shift $(($# > 0 ? 1 : 0))
[ $# -eq 0 ] || TARGETS=("$@")
mkdir -p "$DIR/artifacts"
export ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
failed=()
for t in "${TARGETS[@]}"; do
  mkdir -p "$DIR/corpus/$t"
  log="$DIR/fuzz-$t.log"
  status=0
  # One process per target (-jobs would fork more): the machine is shared. A single
  # allocation above 256 MB is a finding: no input here is more than a few kB.
  "$DIR/fuzz/${t}_fuzzer" -max_total_time="$seconds" -timeout=10 -malloc_limit_mb=256 \
    -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$ROOT/$DIR/artifacts/$t-" \
    "$DIR/corpus/$t" "fuzz/corpus/$t" >"$log" 2>&1 || status=$?
  runs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$log" | tail -1 || true)
  echo "fuzz: $t: ${runs:-?} executions in $seconds s, $cov, corpus $(ls "$DIR/corpus/$t" | wc -l)"
  if [ $status -ne 0 ]; then
    failed+=("$t")
    echo "fuzz: $t FOUND A PROBLEM (exit $status); $log:" >&2
    grep -A40 -m1 -E '^==[0-9]+==ERROR|runtime error|deadly signal|out-of-memory|timeout' "$log" >&2 || tail -40 "$log" >&2
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz: findings in ${failed[*]} (inputs in $DIR/artifacts/)" >&2
  exit 1
fi
echo "fuzz: no findings"
